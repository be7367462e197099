//! Compiles the runtime's compute passes in `glsl/` to SPIR-V with naga (pure Rust, no shaderc).
//! The shaders are the lines of `glsl/shaders.txt`, the one list: the SPIR-V lands in OUT_DIR
//! with `OUT_DIR/shaders.rs`, a `Shader` constant per line that the pass table,
//! `src/vk/passes.rs`, includes; it is never committed.
//! A shader may be built in several variants, each with its own `#define`s (skinning and
//! tangents: K = 4, 8), and may `#include "file.glsl"` from its folder (naga has no `#include`:
//! see [`splice`]).
//! rrskin-render's build script (`tools/render/build.rs`) includes this file for [`build`]
//! (the stage follows the file extension: `.vert`, `.frag`, else compute).

use std::fmt::Write;
use std::path::Path;

fn main() {
    build(Path::new("glsl"));
}

/// One line of a `shaders.txt`: output name, source file, `NAME=value` defines.
struct Shader<'a> {
    name: &'a str,
    source: &'a str,
    defines: Vec<(&'a str, &'a str)>,
}

/// The shaders `dir/shaders.txt` lists (blank lines and `#` comments skipped).
fn list(text: &str) -> Vec<Shader<'_>> {
    let lines = text.lines().map(str::trim);
    let lines = lines.filter(|l| !l.is_empty() && !l.starts_with('#'));
    lines
        .map(|line| {
            let mut words = line.split_whitespace();
            let mut word = || {
                words
                    .next()
                    .unwrap_or_else(|| panic!("shaders.txt: {line}"))
            };
            let (name, source) = (word(), word());
            let defines = (words.map(|d| d.split_once('=')))
                .map(|d| d.unwrap_or_else(|| panic!("shaders.txt: a define is NAME=value: {line}")))
                .collect();
            Shader {
                name,
                source,
                defines,
            }
        })
        .collect()
}

/// Compiles each shader of `dir/shaders.txt` to `OUT_DIR/<output name>.spv` and lists them in
/// `OUT_DIR/shaders.rs` as `pub const NAME: Shader = Shader { glsl, defines, spirv };` (`glsl`
/// and `defines` in test builds only). A build script fails by panicking: the message names the file and gives
/// naga's diagnostic.
pub fn build(dir: &Path) {
    let out_dir = std::env::var("OUT_DIR").expect("cargo sets OUT_DIR");
    let text = read(&dir.join("shaders.txt"));
    let mut consts = String::new();
    for Shader {
        name,
        source: src,
        defines,
    } in list(&text)
    {
        let path = dir.join(src);
        let source = splice(dir, &read(&path));
        let words = compile(&path, &source, &defines);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let spv = Path::new(&out_dir).join(format!("{name}.spv"));
        std::fs::write(&spv, bytes).expect("writing SPIR-V to OUT_DIR");
        let upper = name.to_uppercase();
        writeln!(
            consts,
            "pub const {upper}: Shader = Shader {{ #[cfg(test)] glsl: {src:?}, #[cfg(test)] defines: &{defines:?}, spirv: include_bytes!({spv:?}) }};"
        )
        .expect("writing to a String");
    }
    std::fs::write(Path::new(&out_dir).join("shaders.rs"), consts)
        .expect("writing shaders.rs to OUT_DIR");
}

fn read(path: &Path) -> String {
    println!("cargo:rerun-if-changed={}", path.display());
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

/// `source` with each line `#include "name"` replaced by the file `dir/name` (one level: an
/// included file includes nothing), so that passes share functions (the key predictors).
fn splice(dir: &Path, source: &str) -> String {
    let mut out = String::with_capacity(source.len());
    for line in source.lines() {
        match line.trim().strip_prefix("#include ") {
            Some(name) => out.push_str(&read(&dir.join(name.trim().trim_matches('"')))),
            None => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

fn compile(path: &Path, source: &str, defines: &[(&str, &str)]) -> Vec<u32> {
    use naga::{back::spv, front::glsl, valid};
    let stage = match path.extension().and_then(|e| e.to_str()) {
        Some("vert") => naga::ShaderStage::Vertex,
        Some("frag") => naga::ShaderStage::Fragment,
        _ => naga::ShaderStage::Compute,
    };
    let mut options = glsl::Options::from(stage);
    for (k, v) in defines {
        options.defines.insert((*k).to_string(), (*v).to_string());
    }
    let mut module = glsl::Frontend::default()
        .parse(&options, source)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(source)));
    for entry in &mut module.entry_points {
        workgroup_barriers(&mut entry.function.body);
    }
    for (_, function) in module.functions.iter_mut() {
        workgroup_barriers(&mut function.body);
    }
    let info = valid::Validator::new(valid::ValidationFlags::all(), valid::Capabilities::all())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(source)));
    let spv_options = spv::Options {
        lang_version: (1, 3),
        // No coordinate-space flip (graphics would come out upside down: the shaders write
        // Vulkan's clip space); no injected loop counters (they cost in the GEMM inner loop and
        // our loops are bounded by push constants the runtime checks).
        flags: spv::WriterFlags::empty(),
        force_loop_bounding: false,
        emit_int_div_checks: false,
        // No zeroing of shared memory at each workgroup's start (naga's default polyfill: a
        // store per variable and a barrier, every workgroup): every shader writes its shared
        // memory before a barrier and reads it after (glsl/bounds.comp, dense_product.comp).
        zero_initialize_workgroup_memory: spv::ZeroInitializeWorkgroupMemoryMode::None,
        ..Default::default()
    };
    let pipeline = spv::PipelineOptions {
        shader_stage: stage,
        entry_point: "main".to_string(),
    };
    spv::write_vec(&module, &info, &spv_options, Some(&pipeline))
        .unwrap_or_else(|e| panic!("{}: SPIR-V output: {e}", path.display()))
}

/// GLSL's `barrier()` as the workgroup barrier it is, `OpControlBarrier(Workgroup, Workgroup,
/// AcquireRelease | WorkgroupMemory)` as glslang emits it. naga's GLSL front end reads it as
/// `Barrier::all()`, and its SPIR-V back end then gives the barrier:
/// - with SUB_GROUP, a *subgroup* execution scope: where a workgroup spans several subgroups
///   (64 invocations are two warps on NVIDIA) they do not wait for each other, and a warp with
///   no columns to multiply runs ahead into the GEMM's next tile of shared memory while another
///   still reads the last one (a wrong mesh that changes from run to run; lavapipe runs every
///   barrier across the workgroup, so it never showed);
/// - with STORAGE and TEXTURE, a *device* memory scope over uniform and image memory: a
///   device-wide acquire-release in the GEMM's tile loop, which GLSL's `barrier()` never asks
///   for (only shared memory; no shader here orders buffer accesses by a barrier, it reads
///   its buffers before and writes them after).
///
/// `passes::tests` checks every barrier's scopes and semantics in the SPIR-V.
fn workgroup_barriers(block: &mut naga::Block) {
    use naga::Statement as S;
    for statement in block.iter_mut() {
        match statement {
            S::ControlBarrier(flags) => *flags = naga::Barrier::WORK_GROUP,
            S::Block(inner) => workgroup_barriers(inner),
            S::If { accept, reject, .. } => {
                workgroup_barriers(accept);
                workgroup_barriers(reject);
            }
            S::Loop {
                body, continuing, ..
            } => {
                workgroup_barriers(body);
                workgroup_barriers(continuing);
            }
            S::Switch { cases, .. } => cases
                .iter_mut()
                .for_each(|case| workgroup_barriers(&mut case.body)),
            _ => {}
        }
    }
}
