//! The table of compute passes: one [`PassDesc`] per pipeline. The order they run in, and the
//! barriers between them, are the schedule in `batch.rs`.

use super::pass::Binding::{Model, Reads, Updates, Writes};
use super::pass::CrowdBuffer as Crowd;
use super::pass::Extent::{
    CharacterColumns, Characters, CorrectedProxies, Correctives, PredictorsAndBones, Proxies,
    ProxyRows, Vertices,
};
use super::pass::ModelBuffer as M;
use super::pass::{
    extended, indexed_enum, over, Axis, Binding, Dims, PassDesc, PushWord as W, ONE,
};
use crate::normals::NormalMode;

/// The SPIR-V of `glsl/shaders.txt`, one [`Shader`] constant a line (build.rs writes them).
mod shaders {
    use super::super::pass::Shader;
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

indexed_enum! {
    /// A pipeline of the table. Adding one means: its shader and its line in
    /// `glsl/shaders.txt`, a variant here with its [`PassDesc`] below (the compiler asks for
    /// the arm of `desc`), and its place in `batch.rs`'s schedule (a test checks that every
    /// pass has one). A new buffer is a variant of `ModelBuffer` or `CrowdBuffer`: the
    /// compiler asks for its size (`memory.rs`) and its data (`gpu_model.rs`) or its usage
    /// (`crowd.rs`; the contract's table row, `contract.rs`).
    pub enum Pass {
        Predict,
        DenseProduct,
        SparseProduct,
        FusedProduct,
        FusedCorrectedProduct,
        SkinK4,
        SkinK8,
        SkinNormalsK4,
        SkinNormalsK8,
        SkinFramesK4,
        SkinFramesK8,
        Normals,
        Bounds,
        TangentsK4,
        TangentsK8,
        CorrectiveWeights,
        ProxyCorrectives,
        ProxyCorrectivesGravity,
    }
}

impl Pass {
    pub fn desc(self) -> &'static PassDesc {
        match self {
            Pass::Predict => &PREDICT,
            Pass::DenseProduct => &DENSE_PRODUCT,
            Pass::SparseProduct => &SPARSE_PRODUCT,
            Pass::FusedProduct => &FUSED_PRODUCT,
            Pass::FusedCorrectedProduct => &FUSED_CORRECTED_PRODUCT,
            Pass::SkinK4 => &SKIN_K4,
            Pass::SkinK8 => &SKIN_K8,
            Pass::SkinNormalsK4 => &SKIN_NORMALS_K4,
            Pass::SkinNormalsK8 => &SKIN_NORMALS_K8,
            Pass::SkinFramesK4 => &SKIN_FRAMES_K4,
            Pass::SkinFramesK8 => &SKIN_FRAMES_K8,
            Pass::Normals => &NORMALS,
            Pass::Bounds => &BOUNDS,
            Pass::TangentsK4 => &TANGENTS_K4,
            Pass::TangentsK8 => &TANGENTS_K8,
            Pass::CorrectiveWeights => &CORRECTIVE_WEIGHTS,
            Pass::ProxyCorrectives => &PROXY_CORRECTIVES,
            Pass::ProxyCorrectivesGravity => &PROXY_CORRECTIVES_GRAVITY,
        }
    }

    pub fn runs_for(self, d: &Dims) -> bool {
        (self.desc().runs)(d)
    }

    /// The passes a model of sizes `d` runs.
    pub fn of_model(d: &Dims) -> impl Iterator<Item = Pass> + '_ {
        Pass::ALL.into_iter().filter(|p| p.runs_for(d))
    }

    /// Descriptor sets and storage-buffer descriptors of one chunk of a crowd of `d`.
    pub fn descriptors_per_chunk(d: &Dims) -> (u32, u32) {
        Pass::of_model(d).fold((0, 0), |(sets, buffers), p| {
            (sets + 1, buffers + p.desc().bindings.len() as u32)
        })
    }
}

/// One crowd of each kind the table tells apart: plain LBS (P = 0) or reduced with a dense or
/// a block-sparse [C1 | C2], the latter with or without its predictors fused in, for each K,
/// with and without bounds, with and without tangents, with and without correctives, and (of
/// reduced models) with and without proxy correctives (seeing gravity or not), applied in a
/// fused product or not. (A key's kind changes no pass: each reads the keys' records.)
#[cfg(test)]
pub fn model_kinds() -> impl Iterator<Item = Dims> {
    let corrected = plain_model_kinds().flat_map(|d| {
        [(0, 0), (3, 2)].map(|(correctives, drivers)| Dims {
            correctives,
            drivers,
            ..d
        })
    });
    corrected.flat_map(|d| {
        let proxies = [(0, 0, false), (2, 3, true), (1, 0, true), (2, 4, false)];
        (proxies.into_iter())
            .filter(move |&(e, _, _)| e <= d.proxies)
            .flat_map(move |(corrected_proxies, kernels, linear_features)| {
                [(false, false), (true, false), (false, true), (true, true)].map(
                    move |(correctives_in_product, gravity)| Dims {
                        corrected_proxies,
                        kernels,
                        linear_features,
                        correctives_in_product,
                        gravity: gravity && corrected_proxies > 0,
                        ..d
                    },
                )
            })
    })
}

#[cfg(test)]
fn plain_model_kinds() -> impl Iterator<Item = Dims> {
    let products = [
        (0, false, false),
        (3, false, false),
        (3, true, false),
        (3, true, true),
    ];
    let kinds = crate::model::SUPPORTED_INFLUENCES.map(|k| products.map(|(p, s, f)| (k, p, s, f)));
    let outputs = [(false, false), (true, false), (false, true), (true, true)]
        .into_iter()
        .flat_map(|o| [NormalMode::Recomputed, NormalMode::Transformed].map(|n| (o, n)));
    kinds
        .into_iter()
        .flatten()
        .flat_map(move |(k, proxies, sparse, fused)| {
            outputs
                .clone()
                .map(move |((bounds, tangents), normals)| Dims {
                    vertices: 10,
                    proxies,
                    bones: 2,
                    influences: k as usize,
                    bounds,
                    tangents,
                    normals,
                    sparse,
                    fused,
                    correctives_in_product: false,
                    correctives: 0,
                    drivers: 0,
                    corrected_proxies: 0,
                    kernels: 0,
                    linear_features: false,
                    gravity: false,
                })
        })
}

/// Key gradients D_ℓ(q) for every (predictor, character), written with the bone transforms into
/// B = [d; q], the right-hand side of the GEMM, and the bones into the skinning palette
/// [t; q]. Reduced models (P > 0) whose product does not evaluate them itself.
const PREDICT: PassDesc = PassDesc {
    shader: shaders::PREDICT,
    bindings: &[
        Reads(Crowd::Bones),
        Model(M::Parents),
        Model(M::Keys),
        Writes(Crowd::Rhs),
        Writes(Crowd::Palette),
    ],
    push: &[W::Proxies, W::Bones, W::Characters],
    // local_size_x = 64 over predictors then bones, one row of groups per character.
    groups: [over(PredictorsAndBones, 64), over(Characters, 1), ONE],
    runs: |d| d.proxies > 0 && !d.fused,
};

/// Proxy transforms T (4P x 3C) = [C1 | C2] (4P x (3P + 4J)) · B ((3P + 4J) x 3C) for all
/// characters of a chunk as one tiled matrix product.
const DENSE_PRODUCT: PassDesc = PassDesc {
    shader: shaders::DENSE_PRODUCT,
    bindings: &[
        Model(M::ProductMatrix),
        Reads(Crowd::Rhs),
        Writes(Crowd::Palette),
    ],
    push: &[W::Proxies, W::Bones, W::Characters],
    // Output tile of one workgroup: 256 columns x 16 rows (4 proxies), see the shader.
    groups: [over(CharacterColumns, 256), over(ProxyRows, 16), ONE],
    runs: |d| d.proxies > 0 && !d.sparse,
};

/// The same T for a model whose [C1 | C2] is stored block-sparse per proxy (`GpuModel::new`
/// chooses): each (character, proxy) sums only the columns the proxy's rows touch.
const SPARSE_PRODUCT: PassDesc = PassDesc {
    shader: shaders::SPARSE_PRODUCT,
    bindings: &[
        Model(M::ProductOffsets),
        Model(M::ProductColumns),
        Model(M::ProductValues),
        Reads(Crowd::Rhs),
        Writes(Crowd::Palette),
    ],
    push: &[W::Proxies, W::Bones, W::Characters],
    // local_size_x = 64 over characters, one row of groups per proxy.
    groups: [over(Characters, 64), over(Proxies, 1), ONE],
    runs: |d| d.proxies > 0 && d.sparse && !d.fused,
};

/// The same T for a block-sparse model whose proxies read at most one key each: each
/// (character, proxy) evaluates its key's predictor from the bones and multiplies B's entries
/// as it makes them, so neither the predictor pass nor B's round trip through memory remain.
const FUSED_PRODUCT: PassDesc = PassDesc {
    shader: shaders::FUSED_PRODUCT,
    bindings: &FUSED_BINDINGS,
    push: &[W::Proxies, W::Bones, W::Characters],
    // As the sparse product's, and a row per bone (copied into the palette).
    groups: [over(Characters, 64), over(PredictorsAndBones, 1), ONE],
    runs: |d| d.proxies > 0 && d.fused && !fused_corrects(d),
};

/// Whether a fused product applies the proxy correctives itself (never those that see gravity:
/// the product binds no up vectors).
pub(super) fn fused_corrects(d: &Dims) -> bool {
    d.fused && d.corrected_proxies > 0 && d.correctives_in_product && !d.gravity
}

/// The fused product of a model with proxy correctives: each corrected proxy's invocation
/// applies `T_e (I + E_e)` (as the proxy-correctives pass does) before it stores `T_e`, so that
/// the frame runs one dispatch and one barrier fewer (what small crowds pay for).
const FUSED_CORRECTED_PRODUCT: PassDesc = PassDesc {
    shader: shaders::FUSED_CORRECTED_PRODUCT,
    bindings: &extended::<7, 10>(FUSED_BINDINGS, &PROXY_CORRECTIVE_DATA),
    push: &PROXY_CORRECTIVE_PUSH,
    runs: |d| d.proxies > 0 && d.fused && fused_corrects(d),
    ..FUSED_PRODUCT
};

/// Pose-space corrective weights w = map · φ(q) for every (target, character), from the
/// drivers' rotations relative to their parents. Models with correctives only.
const CORRECTIVE_WEIGHTS: PassDesc = PassDesc {
    shader: shaders::CORRECTIVE_WEIGHTS,
    bindings: &[
        Reads(Crowd::Bones),
        Model(M::Parents),
        Model(M::CorrectiveDrivers),
        Model(M::CorrectiveMap),
        Writes(Crowd::CorrectiveWeights),
    ],
    push: &[W::Correctives, W::Drivers, W::Bones, W::Characters],
    // local_size_x = 64 over targets, one row of groups per character.
    groups: [over(Correctives, 64), over(Characters, 1), ONE],
    runs: |d| d.correctives > 0,
};

/// Proxy correctives (docs/method.md §21): each corrected proxy's T_e = [M | t], as the product
/// wrote it into the palette, becomes T_e (I + E_e) = [M (I + A) | t + M b] in place, E_e =
/// [A | b] = Σ_f x_f G_ef from the features of its drivers (their φ_b = vec(R_b − I), then the
/// kernels exp(−|φ_b − z_cb|² / w_b) − exp(−|z_cb|² / w_b)). After whichever product ran, before
/// skinning. Models with proxy correctives only.
const PROXY_CORRECTIVES: PassDesc = PassDesc {
    shader: shaders::PROXY_CORRECTIVES,
    bindings: &PROXY_CORRECTIVES_BINDINGS,
    push: &PROXY_CORRECTIVE_PUSH,
    // local_size_x = 64, four characters an invocation (256 a workgroup), one row of
    // groups per corrected proxy.
    groups: [over(Characters, 256), over(CorrectedProxies, 1), ONE],
    runs: |d| d.corrected_proxies > 0 && !fused_corrects(d) && !d.gravity,
};

/// The same for proxy correctives that see gravity (`Dims::gravity`): the shader's `GRAVITY`
/// build, which also reads each character's up vector.
const PROXY_CORRECTIVES_GRAVITY: PassDesc = PassDesc {
    shader: shaders::PROXY_CORRECTIVES_GRAVITY,
    bindings: &extended::<6, 7>(PROXY_CORRECTIVES_BINDINGS, &[Reads(Crowd::Ups)]),
    runs: |d| d.corrected_proxies > 0 && d.gravity,
    ..PROXY_CORRECTIVES
};

/// The proxy-correctives pass's: the bones, their parents and the correctives' data in, the
/// palette updated.
const PROXY_CORRECTIVES_BINDINGS: [Binding; 6] = extended::<2, 6>(
    [Reads(Crowd::Bones), Model(M::Parents)],
    &extended::<3, 4>(PROXY_CORRECTIVE_DATA, &[Updates(Crowd::Palette)]),
);

/// Matrix-palette skinning over the palette [proxies (P); bones (J)]: of a reduced model all
/// of it in the Palette buffer, of a plain LBS model the bones in place; one pipeline per K.
/// With correctives (N > 0), the rest position plus the weighted targets is skinned.
const SKIN_K4: PassDesc = PassDesc {
    shader: shaders::SKIN_K4,
    bindings: &SKIN_BINDINGS,
    push: &[
        W::Vertices,
        W::Proxies,
        W::Bones,
        W::Characters,
        W::Correctives,
    ],
    groups: PER_VERTEX,
    runs: |d| d.influences == 4 && d.normals == NormalMode::Recomputed,
};

const SKIN_K8: PassDesc = PassDesc {
    shader: shaders::SKIN_K8,
    runs: |d| d.influences == 8 && d.normals == NormalMode::Recomputed,
    ..SKIN_K4
};

/// Skinning with transformed normals (`crate::normals`): the rest normals, stored after the
/// rest positions and targets, through the cofactor of each vertex's blended matrix, written
/// beside the positions, so that neither the normals pass nor the tangents pass runs; one
/// pipeline per K. Crowds without tangents.
const SKIN_NORMALS_K4: PassDesc = PassDesc {
    shader: shaders::SKIN_NORMALS_K4,
    bindings: &SKIN_NORMALS_BINDINGS,
    runs: |d| d.influences == 4 && d.normals == NormalMode::Transformed && !d.tangents,
    ..SKIN_K4
};

const SKIN_NORMALS_K8: PassDesc = PassDesc {
    shader: shaders::SKIN_NORMALS_K8,
    runs: |d| d.influences == 8 && d.normals == NormalMode::Transformed && !d.tangents,
    ..SKIN_NORMALS_K4
};

/// As [`SKIN_NORMALS_K4`], and the tangent frames: the rest tangent through the blended 3x3,
/// made orthogonal to the transformed normal. Crowds with tangents.
const SKIN_FRAMES_K4: PassDesc = PassDesc {
    shader: shaders::SKIN_FRAMES_K4,
    bindings: &extended::<8, 10>(
        SKIN_NORMALS_BINDINGS,
        &[Model(M::RestTangents), Writes(Crowd::Tangents)],
    ),
    runs: |d| d.influences == 4 && d.normals == NormalMode::Transformed && d.tangents,
    ..SKIN_K4
};

const SKIN_FRAMES_K8: PassDesc = PassDesc {
    shader: shaders::SKIN_FRAMES_K8,
    runs: |d| d.influences == 8 && d.normals == NormalMode::Transformed && d.tangents,
    ..SKIN_FRAMES_K4
};

/// Normals gathered from each vertex's 1-ring fans (`crate::normals::Fans`; no atomics).
/// Crowds with recomputed normals.
const NORMALS: PassDesc = PassDesc {
    shader: shaders::NORMALS,
    bindings: &[
        Reads(Crowd::Positions),
        Model(M::FanOffsets),
        Model(M::Fans),
        Writes(Crowd::Normals),
    ],
    push: &[W::Vertices, W::Characters],
    groups: PER_VERTEX,
    runs: |d| d.normals == NormalMode::Recomputed,
};

/// Per-character axis-aligned boxes of the positions: one workgroup per character reduces its
/// vertices in shared memory (no atomics). Crowds created with bounds only.
const BOUNDS: PassDesc = PassDesc {
    shader: shaders::BOUNDS,
    bindings: &[Reads(Crowd::Positions), Writes(Crowd::Bounds)],
    push: &[W::Vertices, W::Characters],
    groups: [over(Characters, 1), ONE, ONE],
    runs: |d| d.bounds,
};

/// Tangent frames: each vertex's rest tangent through its blended palette matrix, made
/// orthogonal to its normal; one pipeline per K. Crowds created with tangents and recomputed
/// normals (with transformed normals, skinning writes them).
const TANGENTS_K4: PassDesc = PassDesc {
    shader: shaders::TANGENTS_K4,
    bindings: &[
        Model(M::SkinIndex),
        Model(M::SkinWeight),
        Model(M::RestTangents),
        Reads(Crowd::Palette),
        Reads(Crowd::Bones),
        Reads(Crowd::Normals),
        Writes(Crowd::Tangents),
    ],
    push: &[W::Vertices, W::Proxies, W::Bones, W::Characters],
    groups: PER_VERTEX,
    runs: |d| d.tangents && d.influences == 4 && d.normals == NormalMode::Recomputed,
};

const TANGENTS_K8: PassDesc = PassDesc {
    shader: shaders::TANGENTS_K8,
    runs: |d| d.tangents && d.influences == 8 && d.normals == NormalMode::Recomputed,
    ..TANGENTS_K4
};

/// The fused product's: the block-sparse [C1 | C2], the bones and the predictors in, the
/// palette out.
const FUSED_BINDINGS: [Binding; 7] = [
    Model(M::ProductOffsets),
    Model(M::ProductColumns),
    Model(M::ProductValues),
    Reads(Crowd::Bones),
    Model(M::Parents),
    Model(M::Keys),
    Writes(Crowd::Palette),
];

/// The proxy correctives' model data (glsl/proxy_correction.glsl).
const PROXY_CORRECTIVE_DATA: [Binding; 3] = [
    Model(M::ProxyTopology),
    Model(M::ProxyKernels),
    Model(M::ProxyMaps),
];

/// The push words of the passes that apply the proxy correctives.
const PROXY_CORRECTIVE_PUSH: [W; 6] = [
    W::Proxies,
    W::Bones,
    W::Characters,
    W::CorrectedProxies,
    W::Kernels,
    W::LinearFeatures,
];

/// Skinning's: the rest positions (and targets, and normals), the influences, the palette
/// (or, for P = 0, the bones) and the corrective weights in, the positions out.
const SKIN_BINDINGS: [Binding; 7] = [
    Model(M::Rest),
    Model(M::SkinIndex),
    Model(M::SkinWeight),
    Reads(Crowd::Palette),
    Reads(Crowd::Bones),
    Writes(Crowd::Positions),
    Reads(Crowd::CorrectiveWeights),
];

/// Skinning with transformed normals: the normals out too.
const SKIN_NORMALS_BINDINGS: [Binding; 8] = extended(SKIN_BINDINGS, &[Writes(Crowd::Normals)]);

/// local_size_x = 64 over vertices, one row of groups per character.
const PER_VERTEX: [Axis; 3] = [over(Vertices, 64), over(Characters, 1), ONE];

#[cfg(test)]
mod tests {
    use super::super::pass::{Binding, CrowdBuffer};
    use super::*;

    /// (binding index, declared `readonly`, block name) of every storage buffer, and the push
    /// block's member names, in source order.
    fn interface(
        source: &str,
        defines: &[(&str, &str)],
    ) -> (Vec<(usize, bool, String)>, Vec<String>) {
        // The lines of this variant: those of `#ifdef NAME .. #endif` blocks only where NAME is
        // defined (no nesting, no #else in these shaders).
        let mut kept = true;
        let variant: Vec<&str> = (source.lines().filter(|line| {
            let line = line.trim();
            if let Some(name) = line.strip_prefix("#ifdef ") {
                kept = defines.iter().any(|(d, _)| *d == name.trim());
                return false;
            }
            if line.starts_with("#endif") {
                kept = true;
                return false;
            }
            kept
        }))
        .collect();
        let buffers = (variant.iter())
            .filter_map(|line| {
                let at = line.find("binding = ")? + "binding = ".len();
                let digits: String = line[at..]
                    .chars()
                    .take_while(char::is_ascii_digit)
                    .collect();
                let index = digits.parse().ok()?;
                let (_, block) = line.split_once("buffer ")?;
                let name = block.split_whitespace().next()?.to_string();
                Some((index, line.contains(") readonly buffer"), name))
            })
            .collect();
        let push = (variant.join("\n"))
            .split_once("layout(push_constant) uniform Push {")
            .and_then(|(_, rest)| rest.split_once('}'))
            .map(|(block, _)| {
                block
                    .split(';')
                    .filter_map(|member| member.split_whitespace().nth(1))
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        (buffers, push)
    }

    fn block_name(binding: Binding) -> &'static str {
        match binding {
            Binding::Model(m) => match m {
                M::Rest => "Rest",
                M::SkinIndex => "SkinIndex",
                M::SkinWeight => "SkinWeight",
                M::Parents => "Parents",
                M::Keys => "Keys",
                M::ProductMatrix => "ProductMatrix",
                M::ProductOffsets => "ProductOffsets",
                M::ProductColumns => "ProductColumns",
                M::ProductValues => "ProductValues",
                M::FanOffsets => "FanOffsets",
                M::Fans => "Fans",
                M::Triangles => "Triangles",
                M::RestTangents => "RestTangents",
                M::CorrectiveDrivers => "Drivers",
                M::CorrectiveMap => "CorrectiveMap",
                M::ProxyTopology => "ProxyTopology",
                M::ProxyKernels => "ProxyKernels",
                M::ProxyMaps => "ProxyMaps",
            },
            Binding::Reads(c) | Binding::Writes(c) | Binding::Updates(c) => match c {
                CrowdBuffer::Bones => "Bones",
                CrowdBuffer::Rhs => "Rhs",
                CrowdBuffer::Palette => "Palette",
                CrowdBuffer::Positions => "Positions",
                CrowdBuffer::Normals => "Normals",
                CrowdBuffer::Bounds => "Bounds",
                CrowdBuffer::Tangents => "Tangents",
                CrowdBuffer::CorrectiveWeights => "CorrectiveWeights",
                CrowdBuffer::Ups => "Ups",
            },
        }
    }

    fn glsl_name(word: W) -> &'static str {
        match word {
            W::Vertices => "V",
            W::Proxies => "P",
            W::Bones => "J",
            W::Characters => "chars",
            W::Correctives => "N",
            W::Drivers => "D",
            W::CorrectedProxies => "E",
            W::Kernels => "C",
            W::LinearFeatures => "L",
        }
    }

    #[test]
    fn bindings_and_push_blocks_are_those_of_the_glsl() {
        for pass in Pass::ALL {
            let d = pass.desc();
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("glsl")
                .join(d.shader.glsl);
            let source = std::fs::read_to_string(&path).expect("the pass's shader");
            let (buffers, push) = interface(&source, d.shader.defines);
            let expected: Vec<(usize, bool, String)> = (d.bindings.iter().enumerate())
                .map(|(i, &b)| {
                    (
                        i,
                        !matches!(b, Binding::Writes(_) | Binding::Updates(_)),
                        block_name(b).to_string(),
                    )
                })
                .collect();
            assert_eq!(
                buffers, expected,
                "{pass:?}: (binding, readonly, block) in {}",
                d.shader.glsl
            );
            let words: Vec<&str> = d.push.iter().map(|&w| glsl_name(w)).collect();
            assert_eq!(push, words, "{pass:?}: push block of {}", d.shader.glsl);
            assert!(d.push.len() <= super::super::pass::MAX_PUSH_WORDS);
        }
    }

    /// Every OpControlBarrier of `spirv` as (execution scope, memory scope, semantics): the
    /// values of the constants its operands name (SPIR-V: a 5-word header, then instructions
    /// whose first word is word count << 16 | opcode).
    fn barriers(spirv: &[u8]) -> Vec<[u32; 3]> {
        const OP_CONSTANT: u32 = 43;
        const OP_CONTROL_BARRIER: u32 = 224;
        let words: Vec<u32> = (spirv.chunks_exact(4))
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        let mut instructions = Vec::new();
        let mut at = 5;
        while at < words.len() {
            let count = (words[at] >> 16) as usize;
            instructions.push(&words[at..at + count.max(1)]);
            at += count.max(1);
        }
        let constant = |id: u32| {
            (instructions.iter())
                .find(|i| i[0] & 0xFFFF == OP_CONSTANT && i[2] == id)
                .map_or(u32::MAX, |i| i[3])
        };
        (instructions.iter())
            .filter(|i| i[0] & 0xFFFF == OP_CONTROL_BARRIER)
            .map(|i| [constant(i[1]), constant(i[2]), constant(i[3])])
            .collect()
    }

    /// GLSL's `barrier()` is `OpControlBarrier(Workgroup, Workgroup, AcquireRelease |
    /// WorkgroupMemory)`, as glslang emits it (build.rs `workgroup_barriers`). naga's SPIR-V
    /// gave it a subgroup execution scope, which let the GEMM's warps race on its shared tile
    /// on a real GPU, and a device memory scope over uniform and image memory, a device-wide
    /// fence in the tile loop; lavapipe shows neither, so the SPIR-V is checked here. Each
    /// shader has exactly the barriers its GLSL writes: none added to zero shared memory.
    #[test]
    fn every_barrier_is_glsl_s_workgroup_barrier_and_no_other_is_added() {
        const WORKGROUP: u32 = 2;
        const ACQUIRE_RELEASE_WORKGROUP_MEMORY: u32 = 0x8 | 0x100;
        let dense = barriers(Pass::DenseProduct.desc().shader.spirv);
        assert!(dense.len() >= 2, "the GEMM's tile barriers: {dense:?}");
        for pass in Pass::ALL {
            let shader = &pass.desc().shader;
            let found = barriers(shader.spirv);
            let expected = [WORKGROUP, WORKGROUP, ACQUIRE_RELEASE_WORKGROUP_MEMORY];
            assert!(
                found.iter().all(|b| *b == expected),
                "{pass:?}: barriers (execution scope, memory scope, semantics) {found:x?} \
                 (scope 1 = Device, 2 = Workgroup, 3 = Subgroup; semantics 0x108 = AcquireRelease \
                 | WorkgroupMemory)"
            );
            let source = std::fs::read_to_string(
                std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("glsl")
                    .join(shader.glsl),
            )
            .expect("the pass's GLSL");
            let written = source.matches("barrier();").count();
            assert_eq!(
                found.len(),
                written,
                "{pass:?}: barriers in {}",
                shader.glsl
            );
        }
    }

    #[test]
    fn passes_are_listed_in_declaration_order() {
        for (i, pass) in Pass::ALL.into_iter().enumerate() {
            assert_eq!(pass as usize, i);
        }
    }

    /// Every model runs exactly one writer of each output, and every crowd buffer its passes
    /// read is either the bone input or written by one of them (the palette by two: the bones
    /// and t, and by the proxy correctives after them where the model has them; with P = 0 it
    /// is bound but never read).
    #[test]
    fn every_model_writes_its_outputs_once_and_reads_only_what_is_written() {
        for d in model_kinds() {
            let writers = |b: CrowdBuffer| {
                Pass::of_model(&d)
                    .filter(|p| p.desc().crowd_accesses().1 & b.bit() != 0)
                    .count()
            };
            assert_eq!(writers(CrowdBuffer::Positions), 1, "{d:?}");
            assert_eq!(writers(CrowdBuffer::Normals), 1, "{d:?}");
            assert_eq!(
                writers(CrowdBuffer::Tangents),
                usize::from(d.tangents),
                "{d:?}"
            );
            assert_eq!(writers(CrowdBuffer::Bounds), usize::from(d.bounds), "{d:?}");
            for p in Pass::of_model(&d) {
                for b in CrowdBuffer::ALL {
                    let input = b == CrowdBuffer::Bones
                        || b == CrowdBuffer::Ups
                        || (d.proxies == 0 && b == CrowdBuffer::Palette)
                        || (d.correctives == 0 && b == CrowdBuffer::CorrectiveWeights);
                    if p.desc().crowd_accesses().0 & b.bit() != 0 && !input {
                        let expected = match b {
                            CrowdBuffer::Palette => {
                                let separate = d.corrected_proxies > 0 && !fused_corrects(&d);
                                1 + usize::from(!d.fused) + usize::from(separate)
                            }
                            _ => 1,
                        };
                        assert_eq!(writers(b), expected, "{p:?} reads {b:?} of {d:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_chunk_has_one_set_per_pass_the_model_runs() {
        let lbs = Dims {
            vertices: 10,
            proxies: 0,
            bones: 2,
            influences: 4,
            bounds: false,
            tangents: false,
            normals: NormalMode::Recomputed,
            sparse: false,
            fused: false,
            correctives_in_product: false,
            correctives: 0,
            drivers: 0,
            corrected_proxies: 0,
            kernels: 0,
            linear_features: false,
            gravity: false,
        };
        // skin (7 buffers) and normals (4)
        assert_eq!(Pass::descriptors_per_chunk(&lbs), (2, 11));
        let bounded = Dims {
            bounds: true,
            ..lbs
        };
        // + bounds (2)
        assert_eq!(Pass::descriptors_per_chunk(&bounded), (3, 13));
        let reduced = Dims {
            proxies: 3,
            influences: 8,
            ..lbs
        };
        // + predict (5) and the GEMM (3)
        assert_eq!(Pass::descriptors_per_chunk(&reduced), (4, 19));
        let sparse = Dims {
            sparse: true,
            ..reduced
        };
        // + predict (5) and the sparse product (5)
        assert_eq!(Pass::descriptors_per_chunk(&sparse), (4, 21));
        let fused = Dims {
            fused: true,
            correctives_in_product: true,
            ..sparse
        };
        // + the fused product (7)
        assert_eq!(Pass::descriptors_per_chunk(&fused), (3, 18));
        let tangents = Dims {
            tangents: true,
            ..fused
        };
        // + tangents (7)
        assert_eq!(Pass::descriptors_per_chunk(&tangents), (4, 25));
        let corrected = Dims {
            correctives: 3,
            drivers: 2,
            ..tangents
        };
        // + the corrective weights (5)
        assert_eq!(Pass::descriptors_per_chunk(&corrected), (5, 30));
        let proxy_corrected = Dims {
            corrected_proxies: 2,
            kernels: 3,
            linear_features: true,
            ..corrected
        };
        // the fused product with the proxy correctives (10) instead of the fused product (7)
        assert_eq!(Pass::descriptors_per_chunk(&proxy_corrected), (5, 33));
        let separate = Dims {
            fused: false,
            correctives_in_product: false,
            ..proxy_corrected
        };
        // predict (5), the sparse product (5) and the proxy correctives (6) instead
        assert_eq!(Pass::descriptors_per_chunk(&separate), (7, 39));
        let transformed = Dims {
            normals: NormalMode::Transformed,
            ..separate
        };
        // skinning with normals and tangents (10) instead of skin (7), normals (4), tangents (7)
        assert_eq!(Pass::descriptors_per_chunk(&transformed), (5, 31));
    }
}
