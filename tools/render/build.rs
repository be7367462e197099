//! Compiles the renderer's shading stages in `glsl/` (the lines of `glsl/shaders.txt`) to
//! SPIR-V into OUT_DIR with the runtime's naga set-up (one GLSL front end for both crates);
//! `src/renderer.rs` embeds them. The vertex stage is built twice: crowd characters
//! (positions, normals) and host meshes with a per-vertex colour.

// The runtime's build script as a module, for its `build`; its `main` is not called here.
#[allow(dead_code)]
#[path = "../../build.rs"]
mod runtime_build;

fn main() {
    runtime_build::build(std::path::Path::new("glsl"));
}
