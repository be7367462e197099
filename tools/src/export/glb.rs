//! A binary glTF 2.0 (GLB) writer for what `rrskin export` makes: one binary buffer, accessors
//! with the bounds the specification asks for, and the JSON assembled by the caller.

use serde_json::{json, Value};

/// The binary chunk under construction and the accessors and views into it.
#[derive(Default)]
pub struct Buffer {
    pub bytes: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
}

/// glTF's componentType codes.
pub const UNSIGNED_SHORT: u32 = 5123;
pub const UNSIGNED_INT: u32 = 5125;
pub const FLOAT: u32 = 5126;

/// bufferView targets.
pub const ARRAY_BUFFER: u32 = 34962;
pub const ELEMENT_ARRAY_BUFFER: u32 = 34963;

impl Buffer {
    /// Appends `data` as a new buffer view (4-byte aligned), returns its index.
    pub fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while self.bytes.len() % 4 != 0 {
            self.bytes.push(0);
        }
        let mut view =
            json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(view);
        self.views.len() - 1
    }

    /// Float vectors of `width` components (`"VEC3"` etc. from the width, `"SCALAR"` for 1),
    /// with min and max (POSITION and animation inputs must have them; every float accessor
    /// gets them).
    pub fn floats(&mut self, data: &[f32], width: usize, target: Option<u32>) -> usize {
        let mut min = vec![f32::INFINITY; width];
        let mut max = vec![f32::NEG_INFINITY; width];
        for row in data.chunks_exact(width) {
            for (i, &x) in row.iter().enumerate() {
                min[i] = min[i].min(x);
                max[i] = max[i].max(x);
            }
        }
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        self.accessor(json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": data.len() / width,
            "type": kind(width),
            "min": min,
            "max": max,
        }))
    }

    /// Unsigned shorts (joint indices), `width` per element.
    pub fn shorts(&mut self, data: &[u16], width: usize) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.accessor(json!({
            "bufferView": view,
            "componentType": UNSIGNED_SHORT,
            "count": data.len() / width,
            "type": kind(width),
        }))
    }

    /// Triangle indices.
    pub fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.accessor(json!({
            "bufferView": view,
            "componentType": UNSIGNED_INT,
            "count": data.len(),
            "type": "SCALAR",
        }))
    }

    fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

fn kind(width: usize) -> &'static str {
    match width {
        1 => "SCALAR",
        2 => "VEC2",
        3 => "VEC3",
        4 => "VEC4",
        _ => "MAT4",
    }
}

/// The GLB container of `document` (without "buffers", "bufferViews" and "accessors", which
/// come from `buffer`).
pub fn encode(mut document: Value, buffer: Buffer) -> Vec<u8> {
    let Buffer {
        mut bytes,
        views,
        accessors,
    } = buffer;
    while bytes.len() % 4 != 0 {
        bytes.push(0);
    }
    document["buffers"] = json!([{"byteLength": bytes.len()}]);
    document["bufferViews"] = Value::Array(views);
    document["accessors"] = Value::Array(accessors);
    let mut text = document.to_string().into_bytes();
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bytes.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bytes);
    out
}
