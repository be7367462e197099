//! A minimal NPY writer (format 1.0, little-endian, C order) for example sets the tools make.

use std::path::Path;

fn write(path: &Path, descr: &str, shape: &[usize], payload: &[u8]) -> std::io::Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_text = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_text}, }}");
    // Magic (6) + version (2) + length (2) + header, padded with spaces to a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(payload);
    std::fs::write(path, bytes)
}

pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> std::io::Result<()> {
    assert_eq!(
        shape.iter().product::<usize>(),
        data.len(),
        "npy: data must fill the shape"
    );
    let payload: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
    write(path, "<f4", shape, &payload)
}

pub fn write_i32(path: &Path, shape: &[usize], data: &[i32]) -> std::io::Result<()> {
    assert_eq!(
        shape.iter().product::<usize>(),
        data.len(),
        "npy: data must fill the shape"
    );
    let payload: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
    write(path, "<i4", shape, &payload)
}
