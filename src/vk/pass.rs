//! What describes a compute pass: its SPIR-V, its storage-buffer bindings in shader order, its
//! push-constant words and its workgroup counts. Pipelines, descriptor layouts, pool sizes,
//! dispatch sizes, device-limit checks and barriers are all derived from a [`PassDesc`]; the
//! passes themselves are listed in `passes.rs`.

use crate::error::{Error, Result};
use crate::normals::NormalMode;

/// The sizes of a model that passes are dispatched and parameterised over, and the optional
/// outputs of the crowd being dispatched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// V
    pub vertices: u32,
    /// P
    pub proxies: u32,
    /// J
    pub bones: u32,
    /// K (4 or 8, checked when the model is loaded)
    pub influences: usize,
    /// Whether the crowd writes per-character bounding boxes (false for a GPU model itself).
    pub bounds: bool,
    /// Whether the crowd writes tangent frames (false for a GPU model itself; only for models
    /// with rest tangents).
    pub tangents: bool,
    /// How the crowd's normals are made (recomputed for a GPU model itself): recomputed by the
    /// normals pass (and tangents by theirs), or transformed in the skinning pass.
    pub normals: NormalMode,
    /// Whether the model stores C1|C2 block-sparse per proxy (the sparse product runs instead
    /// of the dense GEMM; see `GpuModel::new`).
    pub sparse: bool,
    /// Whether, besides, each proxy reads the columns of at most one key, so that the product
    /// evaluates its predictors itself (the fused product runs instead of the predictor pass
    /// and the sparse product; see `GpuModel::new`). Implies `sparse`.
    pub fused: bool,
    /// Whether a fused product applies the proxy correctives itself (one dispatch fewer; on a
    /// GPU their map loads are the same for the whole workgroup), rather than their own pass
    /// doing so four characters an invocation (what a CPU driver, paying every load per lane,
    /// needs). Meaningful for fused models with proxy correctives; see `GpuModel::new`.
    pub correctives_in_product: bool,
    /// N, the pose-space corrective targets (0: none; the weights pass does not run and
    /// skinning adds nothing).
    pub correctives: u32,
    /// D, the corrective driver bones (0 without correctives).
    pub drivers: u32,
    /// E, the proxies corrected by proxy correctives (0: none; their pass does not run).
    pub corrected_proxies: u32,
    /// C, the proxy correctives' kernel centres per joint (0 without kernels).
    pub kernels: u32,
    /// Whether the proxy correctives' features include the 9 linear φ_b per driver.
    pub linear_features: bool,
    /// Whether they include the 3 gravity features γ_b per driver, from each character's up
    /// (their own pass applies them then, never a fused product, which has no binding left).
    pub gravity: bool,
}

/// An enum whose variants index arrays: `ALL` lists them in declaration order
/// (`ALL[v as usize] == v`) and `COUNT` counts them, both derived from the one declaration.
macro_rules! indexed_enum {
    ($(#[$meta:meta])* pub enum $name:ident { $($(#[$vmeta:meta])* $variant:ident,)* }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum $name { $($(#[$vmeta])* $variant,)* }

        impl $name {
            pub const ALL: [$name; [$($name::$variant),*].len()] = [$($name::$variant),*];
            pub const COUNT: usize = Self::ALL.len();
        }
    };
}
pub(crate) use indexed_enum;

indexed_enum! {
    /// A buffer of the GPU model, uploaded once and only ever read; sized by
    /// `memory::model_buffer_bytes`, filled from `gpu_model::UploadData::of`.
    pub enum ModelBuffer {
        /// (2 + N) x V x 3 f32: the rest positions, the N corrective targets, then the rest
        /// normals (one buffer, so that skinning binds fewer storage buffers)
        Rest,
        SkinIndex,
        SkinWeight,
        /// J i32 bone parents
        Parents,
        /// u32, the P keys' records, each its kind's tag and words (`model::key_words`)
        Keys,
        /// [C1 | C2] dense: 4P x (3P + 4J) f32, row-major (empty where block-sparse)
        ProductMatrix,
        /// P + 1 u32: proxy e's stored columns are entries offsets[e] .. offsets[e + 1]
        ProductOffsets,
        /// one u32 per stored column: its index k in [C1 | C2]
        ProductColumns,
        /// one vec4 per stored column: rows 4e .. 4e + 3 of [C1 | C2] at that column
        ProductValues,
        /// V + 1 u32: vertex a's 1-ring fans are entries offsets[a] .. offsets[a + 1]
        FanOffsets,
        /// u32 per entry, the fans' pivots flagged (`crate::normals::Fans`)
        Fans,
        Triangles,
        /// V x vec4 rest tangents (xyz, handedness w); empty for a model without them
        RestTangents,
        /// D u32: the corrective driver bones (empty without correctives)
        CorrectiveDrivers,
        /// N x 9D f32, row-major: the corrective map (empty without correctives)
        CorrectiveMap,
        /// u32, the proxy correctives' indices in one buffer: the E corrected proxies, their
        /// E + 1 driver offsets, then the Σ D_i drivers (empty without proxy correctives; one
        /// buffer, so that the pass binds no more storage buffers than the widest one)
        ProxyTopology,
        /// f32, the proxy correctives' model data: C x J x 9 kernel centres, then J widths
        /// (neither without kernels), the model's up (3, with gravity only), then J feature
        /// ranges of 12 lower and 12 upper bounds (unbounded for a model without ranges)
        ProxyKernels,
        /// f32 (read as vec4s), the proxy correctives' maps: Σ_i F_i x 12 (empty without proxy correctives)
        ProxyMaps,
    }
}

indexed_enum! {
    /// A per-character buffer of a crowd, bound per chunk of characters; sized by
    /// `memory::bytes_per_character`, its copies counted by `memory::crowd_buffer_copies`.
    pub enum CrowdBuffer {
        /// J x 3x4 f32, one copy per frame slot (host-visible)
        Bones,
        /// B = [d; q], the right-hand side of the C1/C2 product: (3P + 4J) x 3 f32
        Rhs,
        /// The skinning palette [t (P proxy transforms); q (J bones)]: (P + J) x 3x4 f32
        Palette,
        Positions,
        Normals,
        Bounds,
        Tangents,
        /// N f32 rounded up to a multiple of 4 (the stride): the pose-space corrective weights
        /// w = map · φ(q) (only with N > 0)
        CorrectiveWeights,
        /// One vec4 per character (xyz its up in its bones' frame), one copy per frame slot
        /// (host-visible; only where the proxy correctives see gravity)
        Ups,
    }
}

impl CrowdBuffer {
    /// This buffer's bit in a [`CrowdBuffer`] set.
    pub const fn bit(self) -> u32 {
        1 << self as u32
    }
}

/// One `layout(std430, binding = i) buffer` of a shader; the GLSL declares it `readonly`
/// unless it is `Writes` or `Updates`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    Model(ModelBuffer),
    Reads(CrowdBuffer),
    Writes(CrowdBuffer),
    /// Read and written in place (the proxy correctives correct the palette's proxies).
    Updates(CrowdBuffer),
}

/// `base` then `extra`, as one array of `O` = N + extra's length bindings (a variant of a pass
/// binds its base's buffers and more, in the order of its shader). Evaluated in const context,
/// where a wrong `O` fails the build.
pub const fn extended<const N: usize, const O: usize>(
    base: [Binding; N],
    extra: &[Binding],
) -> [Binding; O] {
    assert!(N + extra.len() == O, "the extended binding count");
    let mut out = [Binding::Model(ModelBuffer::Rest); O];
    let mut i = 0;
    while i < O {
        out[i] = if i < N { base[i] } else { extra[i - N] };
        i += 1;
    }
    out
}

/// One `uint` of a pass's push-constant block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PushWord {
    Vertices,
    Proxies,
    Bones,
    /// The characters of the chunk being dispatched.
    Characters,
    /// N, the corrective targets (0 without).
    Correctives,
    /// D, the corrective drivers.
    Drivers,
    /// E, the proxies the proxy correctives correct.
    CorrectedProxies,
    /// C, the proxy correctives' kernels per joint.
    Kernels,
    /// 1 where the proxy correctives have linear features, else 0.
    LinearFeatures,
}

/// Push blocks hold at most this many words (far below Vulkan's guaranteed 128 bytes).
pub const MAX_PUSH_WORDS: usize = 6;

impl PushWord {
    pub fn value(self, d: &Dims, characters: u32) -> u32 {
        match self {
            PushWord::Vertices => d.vertices,
            PushWord::Proxies => d.proxies,
            PushWord::Bones => d.bones,
            PushWord::Characters => characters,
            PushWord::Correctives => d.correctives,
            PushWord::Drivers => d.drivers,
            PushWord::CorrectedProxies => d.corrected_proxies,
            PushWord::Kernels => d.kernels,
            PushWord::LinearFeatures => u32::from(d.linear_features),
        }
    }
}

/// What one axis of a dispatch counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    One,
    Vertices,
    /// P + J (predictors, then bones copied into the right-hand side)
    PredictorsAndBones,
    /// 4P rows of the proxy transforms T
    ProxyRows,
    /// P proxies
    Proxies,
    Characters,
    /// 3C columns of T, three per character
    CharacterColumns,
    /// N corrective weights
    Correctives,
    /// E proxies corrected by proxy correctives
    CorrectedProxies,
}

impl Extent {
    fn count(self, d: &Dims, characters: u32) -> u64 {
        let (v, p, j, c) = (
            d.vertices as u64,
            d.proxies as u64,
            d.bones as u64,
            characters as u64,
        );
        match self {
            Extent::One => 1,
            Extent::Vertices => v,
            Extent::PredictorsAndBones => p + j,
            Extent::ProxyRows => 4 * p,
            Extent::Proxies => p,
            Extent::Characters => c,
            Extent::CharacterColumns => 3 * c,
            Extent::Correctives => d.correctives as u64,
            Extent::CorrectedProxies => d.corrected_proxies as u64,
        }
    }

    /// Units per character, for the extents that grow with the chunk.
    fn per_character(self) -> Option<u64> {
        match self {
            Extent::Characters => Some(1),
            Extent::CharacterColumns => Some(3),
            _ => None,
        }
    }

    fn what(self) -> &'static str {
        match self {
            Extent::One => "one workgroup",
            Extent::Vertices => "workgroups over vertices",
            Extent::PredictorsAndBones => "workgroups over predictors and bones",
            Extent::ProxyRows => "workgroups over proxy row blocks",
            Extent::Proxies => "workgroups over proxies",
            Extent::Characters => "workgroups over characters",
            Extent::CharacterColumns => "workgroups over character columns",
            Extent::Correctives => "workgroups over corrective weights",
            Extent::CorrectedProxies => "workgroups over corrected proxies",
        }
    }
}

/// One dispatch axis: ceil(extent / per_group) workgroups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Axis {
    pub extent: Extent,
    pub per_group: u32,
}

/// `per_group` items of `extent` per workgroup.
pub const fn over(extent: Extent, per_group: u32) -> Axis {
    Axis { extent, per_group }
}

/// An axis of a single workgroup.
pub const ONE: Axis = over(Extent::One, 1);

impl Axis {
    fn groups(self, d: &Dims, characters: u32) -> u64 {
        self.extent
            .count(d, characters)
            .div_ceil(self.per_group as u64)
    }
}

/// A line of `glsl/shaders.txt`: build.rs compiles it and writes one of these per line.
pub struct Shader {
    /// The source in `glsl/` (the table's test checks the bindings and push block against it).
    #[cfg(test)]
    pub glsl: &'static str,
    /// The `NAME=value` defines of its line in `glsl/shaders.txt` (`#ifdef` blocks).
    #[cfg(test)]
    pub defines: &'static [(&'static str, &'static str)],
    /// Built by build.rs from `glsl`, with the line's defines.
    pub spirv: &'static [u8],
}

/// A compute pass, described once.
pub struct PassDesc {
    pub shader: Shader,
    /// In shader order: binding i is `bindings[i]`.
    pub bindings: &'static [Binding],
    /// The push-constant block, in shader order.
    pub push: &'static [PushWord],
    /// Workgroups in x, y, z.
    pub groups: [Axis; 3],
    /// Whether a model of these sizes runs the pass (no sets, no dispatch otherwise).
    pub runs: fn(&Dims) -> bool,
}

impl PassDesc {
    pub fn push_bytes(&self) -> u32 {
        4 * self.push.len() as u32
    }

    /// The push-constant words for a dispatch over `characters`, the first `push.len()` used.
    pub fn push_words(&self, d: &Dims, characters: u32) -> [u32; MAX_PUSH_WORDS] {
        let mut words = [0; MAX_PUSH_WORDS];
        for (w, p) in words.iter_mut().zip(self.push) {
            *w = p.value(d, characters);
        }
        words
    }

    /// Workgroup counts for `characters` (within the device's limits: see
    /// [`PassDesc::check_model_groups`] and [`PassDesc::max_characters`]).
    pub fn dispatch(&self, d: &Dims, characters: u32) -> [u32; 3] {
        self.groups.map(|a| a.groups(d, characters) as u32)
    }

    /// Fails if the axes that depend only on the model need more workgroups than `max`.
    pub fn check_model_groups(&self, d: &Dims, max: [u32; 3]) -> Result<()> {
        let model_axes =
            (self.groups.iter().zip(max)).filter(|(a, _)| a.extent.per_character().is_none());
        for (axis, limit) in model_axes {
            let needed = axis.groups(d, 0);
            if needed > limit as u64 {
                return Err(Error::DeviceLimit {
                    what: axis.extent.what(),
                    needed,
                    limit: limit as u64,
                });
            }
        }
        Ok(())
    }

    /// The most characters one dispatch can cover within `max` workgroups per axis.
    pub fn max_characters(&self, max: [u32; 3]) -> u64 {
        self.groups
            .iter()
            .zip(max)
            .filter_map(|(axis, limit)| {
                let units = axis.extent.per_character()?;
                Some(limit as u64 * axis.per_group as u64 / units)
            })
            .min()
            .unwrap_or(u64::MAX)
    }

    /// The crowd buffers the pass reads and writes, as [`CrowdBuffer::bit`] sets.
    pub fn crowd_accesses(&self) -> (u32, u32) {
        self.bindings
            .iter()
            .fold((0, 0), |(reads, writes), b| match b {
                Binding::Model(_) => (reads, writes),
                Binding::Reads(c) => (reads | c.bit(), writes),
                Binding::Writes(c) => (reads, writes | c.bit()),
                Binding::Updates(c) => (reads | c.bit(), writes | c.bit()),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SKIN_LIKE: [Axis; 3] = [over(Extent::Vertices, 64), over(Extent::Characters, 1), ONE];
    const GEMM_LIKE: [Axis; 3] = [
        over(Extent::CharacterColumns, 256),
        over(Extent::ProxyRows, 16),
        ONE,
    ];

    fn desc(groups: [Axis; 3]) -> PassDesc {
        PassDesc {
            shader: Shader {
                #[cfg(test)]
                glsl: "",
                #[cfg(test)]
                defines: &[],
                spirv: &[],
            },
            bindings: &[],
            push: &[],
            groups,
            runs: |_| true,
        }
    }

    const DIMS: Dims = Dims {
        vertices: 130,
        proxies: 5,
        bones: 3,
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

    #[test]
    fn dispatch_rounds_each_axis_up() {
        assert_eq!(desc(SKIN_LIKE).dispatch(&DIMS, 7), [3, 7, 1]);
        // 3 x 100 columns / 256, 20 rows / 16
        assert_eq!(desc(GEMM_LIKE).dispatch(&DIMS, 100), [2, 2, 1]);
    }

    #[test]
    fn character_axes_bound_the_chunk_and_model_axes_the_model() {
        assert_eq!(desc(SKIN_LIKE).max_characters([10, 20, 1]), 20);
        assert_eq!(desc(GEMM_LIKE).max_characters([3, 1, 1]), 256);
        assert_eq!(desc([ONE; 3]).max_characters([1; 3]), u64::MAX);
        assert!(desc(SKIN_LIKE).check_model_groups(&DIMS, [3, 1, 1]).is_ok());
        assert!(matches!(
            desc(SKIN_LIKE).check_model_groups(&DIMS, [2, 1, 1]),
            Err(Error::DeviceLimit {
                what: "workgroups over vertices",
                needed: 3,
                limit: 2
            })
        ));
    }
}
