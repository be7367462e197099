//! Example sets: N pairs (skeleton pose q_i, deformed mesh y_i) from a black-box rig.

pub mod active_bones;
pub mod alembic;
pub mod align;
pub mod example_set;
pub mod fbx_rig;
pub mod gltf;
pub mod gltf_rig;
pub mod npy;
pub mod point_cache;
pub mod preflight;
pub mod tangents;
pub mod vertex_map;
