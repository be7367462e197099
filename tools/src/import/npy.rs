//! NPY files: a minimal writer (format 1.0, little-endian, C order) for example sets the tools
//! make, and the check of a header's shape that reading needs before npyz sees it.

use std::path::Path;

/// Refuses a header whose shape cannot be the file's: dimensions that are not whole numbers, an
/// element count past u64 (npyz's own product overflows on it), or more data than the file
/// holds (which would otherwise be allocated before the read finds it missing), or a header
/// longer than the file. Headers too broken to find a shape in are left to npyz, which refuses
/// them.
pub fn check_shape(bytes: &[u8]) -> Result<(), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Ok(());
    }
    let (start, len): (usize, usize) = match bytes[6] {
        1 => (10, u16::from_le_bytes([bytes[8], bytes[9]]) as usize),
        _ if bytes.len() >= 12 => (
            12,
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
        ),
        _ => return Ok(()),
    };
    // npyz allocates the declared header length before reading it.
    let Some(header) = bytes.get(start..start.saturating_add(len)) else {
        return Err(format!(
            "not a valid .npy file: its header declares {len} bytes, the file holds {}",
            bytes.len() - start
        ));
    };
    let header = String::from_utf8_lossy(header);
    let Some(tuple) = header
        .split_once("shape")
        .and_then(|(_, rest)| rest.split_once('('))
        .and_then(|(_, rest)| rest.split_once(')'))
        .map(|(tuple, _)| tuple)
    else {
        return Ok(());
    };
    let mut elements: u64 = 1;
    for dim in tuple.split(',').map(str::trim).filter(|d| !d.is_empty()) {
        let n: u64 = dim.parse().map_err(|_| {
            format!("not a valid .npy file: shape dimension '{dim}' is not a whole number")
        })?;
        elements = elements.checked_mul(n).ok_or_else(|| {
            format!("not a valid .npy file: shape ({tuple}) has more elements than a file can hold")
        })?;
    }
    // The item size is the descr's trailing digits ('<f4': 4 bytes).
    let item = header
        .split_once("descr")
        .and_then(|(_, rest)| rest.split(['\'', '"']).nth(2))
        .and_then(|descr| {
            let digits = descr.trim_start_matches(|c: char| !c.is_ascii_digit());
            digits.parse::<u64>().ok()
        });
    let data = (bytes.len() - (start + len).min(bytes.len())) as u64;
    if let Some(item) = item {
        let need = elements.saturating_mul(item);
        if need > data {
            return Err(format!(
                "truncated: shape ({tuple}) needs {need} bytes of data, the file holds {data}"
            ));
        }
    }
    Ok(())
}

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
