//! What a model costs at run time, per character, before it runs (docs/method.md §24).
//!
//! Each pass's work is counted from the model's dimensions, as the shaders and the CPU palette
//! do it: the bytes its threads load and store, its multiply-adds, and its special operations
//! (square roots, divisions, transcendentals). A [`Device`]'s rates turn that work into
//! nanoseconds; they were fitted to measured per-pass times (`tools/calibrate-cost.py`,
//! docs/performance.md "Cost model"), so a prediction is as good as the device it was calibrated
//! on, and it is stated as a ratio where a ratio is what carries over:
//!
//! - the two Vulkan frames ([`Target::Recomputed`], [`Target::Transformed`]) as a multiple of
//!   the engine baseline, the frame an engine already runs: SSD's weights, K influences, one
//!   skinning pass with transformed normals (what `rrskin bench` measures as `engine_ms`);
//! - the CPU palette ([`Target::Palette`]) in µs a character on one core: an engine with its own
//!   skinning pays it on top of its own frame.
//!
//! Work is per character at large crowds: per-dispatch costs, which dominate a handful of
//! characters, are left out, and so are the optional outputs (previous positions, bounds,
//! tangents), which cost every model alike.
//!
//! Letters: V vertices, T triangles, J bones, K influences, P proxies (R predictor keys and S
//! delta-mush keys, key s reading n_s bones), nnz the stored columns of `[C1 | C2]`, N
//! pose-space corrective targets of D drivers, E corrected proxies.

use crate::model::{BlockSparse, Key, Model};
use std::ops::{Add, AddAssign, Mul};

/// Where a model's frame runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// The Vulkan frame with normals recomputed from the skinned mesh (the default).
    Recomputed,
    /// The Vulkan frame with normals transformed in the skinning pass, as engines skin.
    Transformed,
    /// The CPU palette ([`crate::palette::Palette::compute`]), one core.
    Palette,
}

impl Target {
    pub const ALL: [Target; 3] = [Target::Recomputed, Target::Transformed, Target::Palette];

    /// As `--json` names it.
    pub fn name(self) -> &'static str {
        match self {
            Target::Recomputed => "recomputed_normals",
            Target::Transformed => "transformed_normals",
            Target::Palette => "palette",
        }
    }
}

/// Work per character: bytes loaded and stored, the load and store instructions a thread
/// issues (a CPU driver pays each once per lane, whatever its width), the gathers among them
/// (loads in a loop whose length the shader reads at run time, at an address read from
/// memory: a position through a fan entry, a product column's right-hand side, a bone through
/// a key's bone index; a skin influence's palette entry is not one: the K loop is compiled
/// in), the streams (an iteration of such a loop whose loads step with the invocation, so
/// neighbouring lanes read neighbouring words: a corrective target's delta), multiply-adds and
/// special operations; and the workgroups launched (the CPU palette: its calls), whose fixed
/// cost small meshes and small passes pay.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Work {
    pub groups: f64,
    pub bytes: f64,
    pub loads: f64,
    pub gathers: f64,
    pub streams: f64,
    pub madds: f64,
    pub specials: f64,
}

impl Work {
    const fn new(bytes: f64, loads: f64, madds: f64, specials: f64) -> Work {
        Work {
            groups: 0.0,
            bytes,
            loads,
            gathers: 0.0,
            streams: 0.0,
            madds,
            specials,
        }
    }

    /// `n` workgroups.
    const fn groups(n: f64) -> Work {
        Work {
            groups: n,
            ..Work::new(0.0, 0.0, 0.0, 0.0)
        }
    }

    /// `n` gathers.
    const fn gathers(n: f64) -> Work {
        Work {
            gathers: n,
            ..Work::new(0.0, 0.0, 0.0, 0.0)
        }
    }

    /// `n` streams.
    const fn streams(n: f64) -> Work {
        Work {
            streams: n,
            ..Work::new(0.0, 0.0, 0.0, 0.0)
        }
    }
}

impl Add for Work {
    type Output = Work;
    fn add(self, o: Work) -> Work {
        Work {
            groups: self.groups + o.groups,
            bytes: self.bytes + o.bytes,
            loads: self.loads + o.loads,
            gathers: self.gathers + o.gathers,
            streams: self.streams + o.streams,
            madds: self.madds + o.madds,
            specials: self.specials + o.specials,
        }
    }
}

impl AddAssign for Work {
    fn add_assign(&mut self, o: Work) {
        *self = *self + o;
    }
}

impl Mul<f64> for Work {
    type Output = Work;
    fn mul(self, n: f64) -> Work {
        Work {
            groups: self.groups * n,
            bytes: self.bytes * n,
            loads: self.loads * n,
            gathers: self.gathers * n,
            streams: self.streams * n,
            madds: self.madds * n,
            specials: self.specials * n,
        }
    }
}

/// What a device takes per unit of [`Work`], per character, in nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rates {
    pub group: f64,
    pub byte: f64,
    pub load: f64,
    pub gather: f64,
    pub stream: f64,
    pub madd: f64,
    pub special: f64,
}

impl Rates {
    fn ns(&self, w: Work) -> f64 {
        self.group * w.groups
            + self.byte * w.bytes
            + self.load * w.loads
            + self.gather * w.gathers
            + self.stream * w.streams
            + self.madd * w.madds
            + self.special * w.specials
    }
}

/// A device the cost model was calibrated on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Device {
    pub name: &'static str,
    /// Whether its Vulkan driver runs on the CPU: then the proxy correctives keep their own
    /// pass rather than the fused product's (as [`crate::vk::GpuModel::new`] chooses).
    pub cpu_driver: bool,
    /// The Vulkan passes' rates.
    pub frame: Rates,
    /// The CPU palette's rates, on one core of the same machine.
    pub palette: Rates,
}

/// Mesa's lavapipe on this project's 2-core x86-64 machines (and the CPU palette on one of
/// their cores): fitted by `tools/calibrate-cost.py`; the fit's error is in docs/performance.md.
pub const LAVAPIPE: Device = Device {
    name: "lavapipe",
    cpu_driver: true,
    frame: Rates {
        group: 0.0,
        byte: 0.07672,
        load: 0.0,
        gather: 3.002,
        stream: 1.360,
        madd: 0.1579,
        special: 0.5366,
    },
    palette: Rates {
        group: 224.6,
        byte: 0.01235,
        load: 0.0,
        gather: 0.3019,
        stream: 0.0,
        madd: 0.02478,
        special: 7.910,
    },
};

/// One pass of a target and its work per character.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassWork {
    pub pass: &'static str,
    pub work: Work,
}

/// A model's predicted cost on one target of one device.
#[derive(Debug, Clone, PartialEq)]
pub struct Cost {
    pub target: Target,
    pub device: &'static str,
    /// The passes that run (the palette's stages), in order.
    pub passes: Vec<PassWork>,
    /// Predicted nanoseconds a character.
    pub ns: f64,
    /// The engine baseline's one pass (Vulkan targets; None for the palette).
    pub engine: Option<Work>,
    /// Its nanoseconds a character.
    pub engine_ns: Option<f64>,
}

impl Cost {
    /// `model`'s cost on `target` of `device`.
    pub fn of(model: &Model, target: Target, device: &Device) -> Cost {
        let dims = Dims::of(model);
        let (passes, rates) = match target {
            Target::Palette => (palette_passes(model, &dims), &device.palette),
            _ => (frame_passes(model, &dims, target, device), &device.frame),
        };
        Cost::priced(passes, target, device, rates, dims.v, dims.k)
    }

    /// The least any model of `vertices` vertices, at most `influences` influences and
    /// `delta_mush_keys` delta-mush keys costs on `target` of `device`: the skinning pass and each
    /// key's rotation fit over one bone, which every such model runs (its other work grows with
    /// what training fits). Training prices a count by it before fitting one: a count whose
    /// floor is over the budget is over.
    pub fn floor(
        vertices: usize,
        influences: usize,
        delta_mush_keys: usize,
        target: Target,
        device: &Device,
    ) -> Cost {
        let (v, k, s) = (vertices as f64, influences as f64, delta_mush_keys as f64);
        let (passes, rates) = match target {
            Target::Palette => {
                let lanes = (s / 8.0).ceil() * 8.0;
                let fits = POLAR * (lanes / PALETTE_POLAR_LANES);
                let keys = PassWork {
                    pass: "delta-mush keys",
                    work: Work::groups(1.0) + fits,
                };
                (vec![keys], &device.palette)
            }
            _ => {
                let keys = PassWork {
                    pass: "predict",
                    work: delta_mush_key(1.0) * s,
                };
                let skin = PassWork {
                    pass: "skinning",
                    work: skinning(v, k, 0.0, target),
                };
                (vec![keys, skin], &device.frame)
            }
        };
        Cost::priced(passes, target, device, rates, v, k)
    }

    fn priced(
        passes: Vec<PassWork>,
        target: Target,
        device: &Device,
        rates: &Rates,
        v: f64,
        k: f64,
    ) -> Cost {
        let ns = passes.iter().map(|p| rates.ns(p.work)).sum();
        let engine = (target != Target::Palette).then(|| skinning(v, k, 0.0, Target::Transformed));
        Cost {
            target,
            device: device.name,
            passes,
            ns,
            engine,
            engine_ns: engine.map(|w| rates.ns(w)),
        }
    }

    /// The Vulkan frame over the engine baseline's (None for the palette).
    pub fn ratio(&self) -> Option<f64> {
        self.engine_ns.map(|engine| self.ns / engine)
    }

    /// Predicted µs a character.
    pub fn microseconds(&self) -> f64 {
        self.ns * 1e-3
    }
}

/// The dimensions the counts read, as `f64`.
struct Dims {
    v: f64,
    j: f64,
    k: f64,
    p: f64,
    /// Every proxy's stored columns (the CPU palette's product reads these always).
    blocks: BlockSparse,
    /// Whether they are the layout the GPU product runs on (else the dense GEMM runs).
    sparse: bool,
}

impl Dims {
    fn of(model: &Model) -> Dims {
        let blocks = BlockSparse::of(model);
        Dims {
            v: model.vertex_count() as f64,
            j: model.bone_count() as f64,
            k: model.influences() as f64,
            p: model.proxy_count() as f64,
            sparse: blocks.is_layout_of(model),
            blocks,
        }
    }
}

/// One joint's rotation relative to its parent and its log (key.glsl `joint_rotation`).
const JOINT_ROTATION: Work = Work {
    gathers: 2.0,
    ..Work::new(100.0, 7.0, 35.0, 3.0)
};
/// exp of a scaled axis (key.glsl `exp_rotation`).
const EXP: Work = Work::new(0.0, 0.0, 50.0, 5.0);
/// The rotation fit of a delta-mush key: the Gram-Schmidt guess (35 multiply-adds, 3 roots
/// and 6 divisions) and 2 Newton steps of 130 multiply-adds and 2 divisions each
/// (glsl/polar.glsl, src/polar.rs).
const POLAR: Work = Work::new(0.0, 0.0, 295.0, 13.0);
/// How many of the CPU palette's rotation fits ([`crate::polar::nearest_rotations_f32`], 8
/// lanes) one core's instructions carry at once, by the calibration: 2 fits the 60-key model
/// without correctives within 1 %, 4 left it 22 % low (the Newton steps vectorise less than
/// the Jacobi sweeps did).
const PALETTE_POLAR_LANES: f64 = 2.0;

/// A predictor key on the GPU: its record (340 bytes), its bones' two rotations, exp and the
/// scale/shear `H x` (key.glsl `predictor_gradient`); a second bone adds one more of each.
fn predictor_key(second: bool) -> Work {
    let one = JOINT_ROTATION * 2.0 + EXP + Work::new(340.0 + 36.0, 25.0, 129.0, 0.0);
    match second {
        true => one + JOINT_ROTATION + EXP + Work::new(0.0, 0.0, 39.0, 0.0),
        false => one,
    }
}

/// A delta-mush key of n bones on the GPU: its covariance (13 words and a bone each) and fit.
fn delta_mush_key(n: f64) -> Work {
    Work::new(100.0 * n + 44.0, 8.0 * n + 5.0, 36.0 * n, 0.0) + Work::gathers(n) + POLAR
}

/// Key ℓ's work on the GPU.
fn key(model: &Model, l: usize) -> Work {
    match &model.keys()[l] {
        Key::Predictor(k) => predictor_key(k.second.is_some()),
        Key::DeltaMush(k) => delta_mush_key(k.terms.len() as f64),
    }
}

/// The skinning pass over V vertices of K influences (and N corrective targets), writing
/// positions, and with [`Target::Transformed`] the normals through the cofactor (skin.comp).
fn skinning(v: f64, k: f64, n: f64, target: Target) -> Work {
    let groups = Work::groups((v / 64.0).ceil());
    let positions = Work::new(
        56.0 * k + 24.0 + 16.0 * n,
        5.0 * k + 6.0 + 4.0 * n,
        12.0 * k + 12.0 + 3.0 * n,
        0.0,
    );
    let normals = Work::new(24.0, 6.0, 30.0, 2.0);
    // The targets' loop runs to N, a push constant: each target's delta a stream (its
    // address steps with the vertex, and the weight is the character's).
    let positions = positions + Work::streams(n);
    match target {
        Target::Transformed => groups + (positions + normals) * v,
        _ => groups + positions * v,
    }
}

/// The Vulkan passes of `target`, as `crate::vk`'s pass table picks them for `model`.
fn frame_passes(model: &Model, d: &Dims, target: Target, device: &Device) -> Vec<PassWork> {
    let mut out = Vec::new();
    let mut pass = |pass, work: Work| {
        if work != Work::default() {
            out.push(PassWork { pass, work });
        }
    };
    let sparse = d.sparse.then_some(&d.blocks);
    let fused = sparse.is_some_and(BlockSparse::one_key_per_proxy);
    let corrected = model.proxy_corrective_count() > 0;
    let corrects_in_product = fused && corrected && !device.cpu_driver && model.up().is_none();
    if d.p > 0.0 {
        let bones = Work::new(144.0 * d.j, 9.0 * d.j, 0.0, 0.0);
        // Invocations of 64 over the keys then the bones (predict.comp, fused_product.comp).
        let rows = Work::groups(((d.p + d.j) / 64.0).ceil());
        let keys = || (0..model.proxy_count()).map(|l| key(model, l));
        match (sparse, fused) {
            (Some(blocks), true) => {
                let own_keys =
                    (0..model.proxy_count()).map(|e| key(model, own_key(blocks, e, d.p)));
                let mut work =
                    rows + bones + own_keys.fold(Work::default(), Add::add) + columns(blocks, d);
                if corrects_in_product {
                    work += proxy_corrections(model, 1.0);
                }
                pass("product", work);
            }
            (Some(blocks), false) => {
                pass(
                    "predict",
                    rows + bones + keys().fold(Work::default(), Add::add),
                );
                let keys_in = Work::new(36.0 * d.p, 3.0 * d.p, 0.0, 0.0);
                let groups = Work::groups(d.p / 64.0);
                pass("product", groups + columns(blocks, d) + keys_in);
            }
            (None, _) => {
                pass(
                    "predict",
                    rows + bones + keys().fold(Work::default(), Add::add),
                );
                // Tiles of 256 characters' columns by 4 proxies (dense_product.comp).
                let (depth, blocks) = (3.0 * d.p + 4.0 * d.j, (d.p / 4.0).ceil());
                let bytes = 12.75 * depth * blocks + 48.0 * d.p;
                let work = Work::new(bytes, bytes / 16.0, 48.0 * depth * blocks, 0.0);
                pass("product", Work::groups(3.0 * blocks / 256.0) + work);
            }
        }
    }
    if corrected && !corrects_in_product {
        // Four characters an invocation share each map row's load (proxy_correctives.comp).
        let groups = Work::groups(model.proxy_corrective_count() as f64 / 256.0);
        pass("proxy correctives", groups + proxy_corrections(model, 4.0));
    }
    if let Some(c) = model.correctives() {
        let (n, drivers) = (model.corrective_count() as f64, c.driver_count() as f64);
        let weights = Work::new(140.0 * drivers, 11.0 * drivers, 36.0 * drivers, 0.0) * n;
        let groups = Work::groups((n / 64.0).ceil());
        pass(
            "corrective weights",
            groups + weights + Work::new(4.0 * n, n, 0.0, 0.0),
        );
    }
    let n = model.corrective_count() as f64;
    pass("skinning", skinning(d.v, d.k, n, target));
    if target == Target::Recomputed {
        let fan = model.normal_fans().entries.len() as f64;
        let bytes = 4.0 * (d.v + 1.0) + 16.0 * fan + 24.0 * d.v;
        let normals = Work::new(bytes, 5.0 * d.v + 4.0 * fan, 6.0 * fan + 3.0 * d.v, d.v)
            + Work::gathers(fan)
            + Work::groups((d.v / 64.0).ceil());
        pass("normals", normals);
    }
    out
}

/// The key proxy e of a fused product evaluates: that of its first key column (one per proxy,
/// [`BlockSparse::one_key_per_proxy`]), else its own.
fn own_key(blocks: &BlockSparse, e: usize, p: f64) -> usize {
    let (columns, _) = blocks.of_proxy(e);
    let key = columns
        .iter()
        .find(|&&k| (k as f64) < 3.0 * p)
        .map(|k| k / 3);
    key.map_or(e, |k| k as usize)
}

/// The block-sparse product's columns: 20 bytes and 12 multiply-adds each, a bone's 48 bytes
/// for each column past the keys', and each proxy's 48 bytes stored.
fn columns(blocks: &BlockSparse, d: &Dims) -> Work {
    let stored = blocks.columns.len() as f64;
    let of_bones = blocks
        .columns
        .iter()
        .filter(|&&k| k as f64 >= 3.0 * d.p)
        .count() as f64;
    let bytes = 20.0 * stored + 48.0 * of_bones + 48.0 * d.p;
    Work::new(bytes, 3.0 * stored + 3.0 * d.p, 12.0 * stored, 0.0) + Work::gathers(stored)
}

/// Every corrected proxy's `T_e (I + E_e)` (proxy_correction.glsl), its map rows loaded once
/// for `sharing` characters: per driver its rotation, clamp bounds and features, per feature
/// row 12 multiply-adds, per kernel a distance and an exponential.
fn proxy_corrections(model: &Model, sharing: f64) -> Work {
    let Some(c) = model.proxy_correctives() else {
        return Work::default();
    };
    let j = model.bone_count();
    let (kernels, rows) = (c.kernel_count(j) as f64, c.features_per_driver(j) as f64);
    let gravity = match c.up {
        Some(_) => Work::new(64.0, 4.0, 45.0, 0.0),
        None => Work::default(),
    };
    let kernel = Work::new(192.0, 9.0, 48.0, 4.0);
    let driver = Work::new(172.0, 12.0, 27.0, 0.0)
        + gravity
        + kernel * kernels
        + Work::new(48.0, 3.0, 0.0, 0.0) * (rows / sharing)
        + Work::new(0.0, 0.0, 12.0, 0.0) * rows;
    let drivers = c.drivers.len() as f64;
    let proxies = c.proxies.len() as f64;
    driver * drivers + Work::new(96.0, 7.0, 36.0, 0.0) * proxies
}

/// The CPU palette's stages ([`crate::palette::Palette::compute`]).
fn palette_passes(model: &Model, d: &Dims) -> Vec<PassWork> {
    let predictors: Vec<_> = model.keys().iter().filter_map(Key::predictor).collect();
    let seconds = predictors.iter().filter(|k| k.second.is_some()).count() as f64;
    let rotations = crate::palette::rotation_bones(model).len() as f64;
    let exp = Work::new(0.0, 0.0, 18.0, 5.0);
    let keys = (Work::new(0.0, 0.0, 126.0, 0.0) + exp) * predictors.len() as f64
        + (Work::new(0.0, 0.0, 37.0, 0.0) + exp) * seconds
        + Work::new(0.0, 0.0, 35.0, 3.0) * rotations;
    // One call a character (its scratch, its bones' copy).
    let mut out = vec![PassWork {
        pass: "predictors",
        work: Work::groups(1.0) + keys,
    }];
    let delta_mush: Vec<_> = model.keys().iter().filter_map(Key::delta_mush).collect();
    if !delta_mush.is_empty() {
        let lanes = (delta_mush.len() as f64 / 8.0).ceil() * 8.0;
        let fits = POLAR * (lanes / PALETTE_POLAR_LANES);
        let terms: usize = delta_mush.iter().map(|k| k.terms.len()).sum();
        let covariance = (Work::new(100.0, 8.0, 36.0, 0.0) + Work::gathers(1.0)) * terms as f64;
        out.push(PassWork {
            pass: "delta-mush keys",
            work: covariance + fits,
        });
    }
    let stored = d.blocks.columns.len() as f64;
    out.push(PassWork {
        pass: "product",
        work: Work::new(
            28.0 * stored + 96.0 * (d.p + d.j),
            2.0 * stored + 7.0 * d.j + 3.0 * d.p,
            12.0 * stored,
            0.0,
        ) + Work::gathers(stored),
    });
    if model.proxy_corrective_count() > 0 {
        out.push(PassWork {
            pass: "proxy correctives",
            work: proxy_corrections(model, 1.0),
        });
    }
    out
}
