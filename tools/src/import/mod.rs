//! Importers: files read into an example set's parts (`crate::set`), then checked against the
//! rig's own skin ([`preflight`]).

pub mod alembic;
pub mod align;
pub mod fbx_rig;
pub mod gltf;
pub mod gltf_rig;
pub mod mesh_sequence;
pub mod npy;
pub mod numpy_folder;
pub mod point_cache;
pub mod preflight;
pub mod tangents;
pub mod vertex_map;
