//! The runtime model's palette on the CPU, in `f32`, for an engine that skins with its own
//! shaders (paper §4.3, Eq. 5–6; docs/method.md §8). No Vulkan: usable without a GPU or a
//! Vulkan loader.
//!
//! Per character, the J bone transforms `q` in and the P + J palette out: the proxies
//! `T_e = Σ_ℓ D_ℓ(q) A_eℓ + Σ_b Q_b B_eb`, where `A_eℓ: (3 x 4)` and `B_eb: (4 x 4)` are the
//! rows 4e..4e + 4 of C1 and C2 seen per key and per bone, then the bones themselves. A vertex
//! shader blends the K entries the [`Skin`] names: `x = Σ_k w_k M_{i_k} [x̂; 1]`, which is
//! [`Palette::skin`]. Normals: the rest normal ([`Skin::rest_normals`]) through the cofactor of
//! M's 3x3, `cof(M) n̂ = n̂.x (c1 × c2) + n̂.y (c2 × c0) + n̂.z (c0 × c1)` for its columns c,
//! normalised (not through M itself: the proxies scale and shear, and only the cofactor keeps a
//! normal perpendicular to the surface then); the tangent through M's 3x3, made orthogonal to
//! that normal. That is the Vulkan runtime's transformed mode
//! ([`crate::NormalMode::Transformed`]; [`crate::cpu::CpuEvaluator::with_normals`] gives the
//! reference), whose angular error against normals recomputed from the skinned mesh `rrskin
//! eval` reports.
//!
//! A model with pose-space correctives (paper §8) adds, per character, N weights
//! ([`Palette::corrective_weights`], linear in the driver joints' rotations) of N rest-space
//! targets ([`Skin::corrective_targets`]): the shader skins `x̂ + Σ_n w_n target_n` instead of
//! `x̂` ([`Palette::skin_positions`]), as a morph target before skinning.
//!
//! A model with proxy correctives (docs/method.md §21) corrects some proxies in place, per
//! character, before they are returned: [`Palette::compute`] gives `T'_e = T_e (I + E_e)`, with
//! `E_e = Σ_f x_f G_ef` from the drivers' rotations (see [`crate::ProxyCorrectives`]), so the
//! palette keeps its P + J entries and an engine's skinning does not change. It evaluates them
//! in `f32` as `glsl/proxy_correctives.comp` does: each driver's features once per character,
//! whichever proxies it drives. Where they see gravity ([`Model::up`]), each character's up
//! vector in its bones' frame is an input too ([`Palette::compute_batch_with_ups`]; the model's
//! up where none is given).
//!
//! A [`Palette`] is immutable after [`Palette::new`]: any number of threads may call
//! [`Palette::compute`] on one at once. Each thread keeps its own scratch (grown on its first
//! call for a model of that size), so a frame allocates nothing.

use crate::cpu::characters;
use crate::error::{Error, Result};
use crate::model::{BlockSparse, FeatureRange, Key, KeyPredictor, Model, ProxyCorrectives};
use crate::polar::nearest_rotations_f32;
use crate::predict::{check_character_ups, delta_mush_covariance_f32, Affine};
use crate::predict::{exp_rotation_f32 as exp_rotation, log_rotation_f32 as log_rotation};
use glam::{Mat3, Vec3};
use std::cell::RefCell;

/// The identity bone transform (the rest pose).
pub const REST: Affine = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// A model prepared for CPU palette evaluation.
#[derive(Debug, Clone)]
pub struct Palette {
    model: Model,
    /// The predictors' keys, compiled.
    predictors: Vec<CompiledPredictor>,
    /// The delta-mush keys (their indices ℓ), fitted [`DELTA_MUSH_LANES`] at a time.
    delta_mush: Vec<usize>,
    /// Bones whose joint rotation some key reads.
    rotations: Vec<u32>,
    /// `[C1 | C2]` by proxy, zero columns left out.
    blocks: BlockSparse,
    rest_normals: Vec<[f32; 3]>,
    /// The corrective drivers (bone, parent), in the order of the map's columns.
    drivers: Vec<(usize, usize)>,
    /// The proxy correctives, compiled (none corrected without them).
    proxy: ProxyTerms,
}

/// A model's proxy correctives (docs/method.md §21, [`crate::ProxyCorrectives`]) compiled for
/// `f32` evaluation, as `glsl/proxy_correctives.comp`: D distinct drivers over the E corrected
/// proxies, F = 9·L + 3·G + C features each (φ_b if L, γ_b if G, then C kernels), computed
/// once per character into scratch `x: (D x F)`, then per proxy `E_e = Σ_f x_f G_ef` over its
/// `D_i F` rows.
#[derive(Debug, Clone, Default)]
struct ProxyTerms {
    /// `(D)` the distinct drivers (bone, parent), ascending: slot s's features are
    /// `x[s * F..(s + 1) * F]`.
    drivers: Vec<(usize, usize)>,
    /// F, the features of one driver.
    features: usize,
    linear: bool,
    /// The model's up where the features see gravity (G).
    up: Option<Vec3>,
    /// `(D x C)` kernel centres, slot s's kernel c at `s * C + c`.
    centres: Vec<[f32; 9]>,
    /// `(D)` kernel widths `w_b` (empty without kernels).
    widths: Vec<f32>,
    /// `(D)` the ranges φ_b and γ_b are clamped into (empty: not clamped).
    ranges: Vec<FeatureRange>,
    /// `(D x C)` each kernel's `exp(−|z|² / w)` at rest, computed as per character (so a
    /// kernel feature is exactly zero at the rest pose).
    at_rest: Vec<f32>,
    /// `(E)` the corrected proxies.
    proxies: Vec<u32>,
    /// `(E + 1)` CSR offsets: proxy i's rows are `rows[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<u32>,
    /// `G: (Σ D_i F x 12)`, the model's maps: row f of a proxy is its `G_ef`, `[A | b]`
    /// row-major.
    rows: Vec<[f32; 12]>,
    /// `(Σ D_i F)` the feature each row multiplies: `x[index[r]]`.
    index: Vec<u32>,
}

/// One key predictor, compiled: `D = Q_parent exp(uW θ~_bone) [exp(u₂W₂ θ~_second)] S`, with
/// `vec(S) = H [θ~_bone; θ~_parent; 1]` (paper Eq. 3–4).
#[derive(Debug, Clone)]
struct CompiledPredictor {
    /// ℓ, the key it predicts.
    key: usize,
    bone: usize,
    parent: Option<usize>,
    uw: Mat3,
    second: Option<(usize, Mat3)>,
    /// H: 9 x 7, row-major.
    h: [f32; 63],
}

/// The mesh an engine skins with the palette, borrowed from the model.
#[derive(Debug, Clone, Copy)]
pub struct Skin<'a> {
    /// K, 4 or 8.
    pub influences: usize,
    /// V x K palette entries: `< P` a proxy, `P + b` bone b.
    pub indices: &'a [u32],
    /// V x K weights, >= 0, summing to 1 per vertex.
    pub weights: &'a [f32],
    pub rest_positions: &'a [[f32; 3]],
    /// The rest mesh's unit normals (area-weighted, shared across welded seams:
    /// [`Model::rest_normals`]), for the shader to take through the cofactor of M.
    pub rest_normals: &'a [[f32; 3]],
    /// V rest tangents (xyz, handedness w), or empty where the model has none.
    pub rest_tangents: &'a [[f32; 4]],
    pub triangles: &'a [[u32; 3]],
    /// N, the pose-space corrective targets (0 without correctives).
    pub correctives: usize,
    /// N x V rest-space deltas, target-major (as glTF morph targets), or empty: vertex a of
    /// target n is `corrective_targets[n * V + a]`, weighted by [`Palette::corrective_weights`].
    pub corrective_targets: &'a [[f32; 3]],
}

impl Skin<'_> {
    /// Vertex a's blended palette matrix `Σ_k w_k M_{i_k}` (3x4 row-major), of one character's
    /// `palette` (P + J entries; not checked here).
    pub fn blended(&self, a: usize, palette: &[Affine]) -> Affine {
        let k = self.influences;
        let mut m = [0.0f32; 12];
        for i in a * k..(a + 1) * k {
            let (w, entry) = (self.weights[i], &palette[self.indices[i] as usize]);
            m.iter_mut().zip(entry).for_each(|(x, e)| *x += w * e);
        }
        m
    }
}

#[derive(Default)]
struct Scratch {
    /// θ~_b per bone (only `rotations` are written).
    theta: Vec<Vec3>,
    /// The product's right-hand side: 3P key columns, then 4J bone columns, each (x, y, z).
    rhs: Vec<Vec3>,
    /// The proxy correctives' features `x: (D x F)` ([`ProxyTerms`]).
    features: Vec<f32>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl Palette {
    /// Compiles `model`'s keys and stores `[C1 | C2]` by proxy, zero columns left out (the
    /// product then costs what the model's sparsity allows: joint-blend proxies read a few
    /// columns each).
    pub fn new(model: Model) -> Result<Palette> {
        let (mut predictors, mut delta_mush) = (Vec::new(), Vec::new());
        for (l, key) in model.keys().iter().enumerate() {
            match key {
                Key::Predictor(k) => predictors.push(CompiledPredictor::new(&model, l, k)),
                Key::DeltaMush(_) => delta_mush.push(l),
            }
        }
        let rotations = rotation_bones(&model);
        let blocks = BlockSparse::of(&model);
        let rest_normals = model.rest_normals();
        let drivers = (model.correctives().map_or(&[][..], |c| &c.drivers).iter())
            .map(|&d| (d as usize, model.parent(d as usize).unwrap_or(d as usize)))
            .collect();
        let proxy = model
            .proxy_correctives()
            .map_or_else(ProxyTerms::default, |c| ProxyTerms::new(&model, c));
        Ok(Palette {
            model,
            predictors,
            delta_mush,
            rotations,
            blocks,
            rest_normals,
            drivers,
            proxy,
        })
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    /// P + J: the palette's length.
    pub fn len(&self) -> usize {
        self.model.proxy_count() + self.model.bone_count()
    }

    /// Never true: a model has at least one bone.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn skin(&self) -> Skin<'_> {
        let parts = self.model.parts();
        Skin {
            influences: self.model.influences(),
            indices: &parts.skin_indices,
            weights: &parts.skin_weights,
            rest_positions: &parts.rest_positions,
            rest_normals: &self.rest_normals,
            rest_tangents: &parts.rest_tangents,
            triangles: &parts.triangles,
            correctives: self.model.corrective_count(),
            corrective_targets: parts.correctives.as_ref().map_or(&[][..], |c| &c.targets),
        }
    }

    /// N: the corrective weights of a character (0 for a model without pose-space correctives).
    pub fn corrective_count(&self) -> usize {
        self.model.corrective_count()
    }

    /// The pose-space corrective weights of one character: `bones` J transforms (as
    /// [`Palette::compute`]'s), `out` N. `w = map · φ`, `φ[9i + 3r + c] = R_i[r][c] − δ_rc`,
    /// `R_i = rot(Q_parent)ᵀ rot(Q_driver)` (docs/method.md §20). Allocates nothing.
    pub fn corrective_weights(&self, bones: &[Affine], out: &mut [f32]) -> Result<()> {
        self.corrective_weights_batch(bones, out)
    }

    /// [`Palette::corrective_weights`] for C characters: `bones` C x J, `out` C x N.
    pub fn corrective_weights_batch(&self, bones: &[Affine], out: &mut [f32]) -> Result<()> {
        let (j, n) = (self.model.bone_count(), self.corrective_count());
        let c = characters(bones, j)?;
        if out.len() != c * n {
            return Err(Error::WrongLength {
                what: "corrective weights (characters x correctives)",
                expected: c * n,
                actual: out.len(),
            });
        }
        let Some(correctives) = self.model.correctives() else {
            return Ok(());
        };
        let width = 9 * self.drivers.len();
        for (q, w) in bones.chunks_exact(j).zip(out.chunks_exact_mut(n)) {
            w.fill(0.0);
            for (i, &(d, p)) in self.drivers.iter().enumerate() {
                let phi = phi_f32(&q[p], &q[d]);
                for (t, w) in w.iter_mut().enumerate() {
                    let row = &correctives.map[t * width + 9 * i..t * width + 9 * i + 9];
                    *w += row.iter().zip(&phi).map(|(m, f)| m * f).sum::<f32>();
                }
            }
        }
        Ok(())
    }

    /// The palette of one character: `bones` J transforms (3x4 row-major, relative to the rest
    /// pose), `out` P + J: the proxies (corrected where the model has proxy correctives), then
    /// the bones. An upright character: its up is the model's.
    pub fn compute(&self, bones: &[Affine], out: &mut [Affine]) -> Result<()> {
        self.compute_batch_with_ups(bones, &[], out)
    }

    /// [`Palette::compute`] for C characters on this thread: `bones` C x J, `out` C x (P + J).
    pub fn compute_batch(&self, bones: &[Affine], out: &mut [Affine]) -> Result<()> {
        self.compute_batch_with_ups(bones, &[], out)
    }

    /// [`Palette::compute_batch`] with each character's up vector in its bones' frame, `ups` C
    /// (or empty: the model's up), for characters tilted by their object transform rather than
    /// their root bone ([`crate::predict::check_ups`]). Only a model whose proxy correctives see
    /// gravity ([`Model::up`]) reads them.
    pub fn compute_batch_with_ups(
        &self,
        bones: &[Affine],
        ups: &[[f32; 3]],
        out: &mut [Affine],
    ) -> Result<()> {
        let c = self.characters(bones, out)?;
        check_character_ups(c, ups)?;
        SCRATCH.with(|scratch| {
            let scratch = &mut *scratch.borrow_mut();
            let j = self.model.bone_count();
            for (ch, (q, out)) in (bones.chunks_exact(j))
                .zip(out.chunks_exact_mut(self.len()))
                .enumerate()
            {
                self.character(q, ups.get(ch).map(|&u| Vec3::from(u)), out, scratch);
            }
        });
        Ok(())
    }

    /// [`Palette::compute_batch_with_ups`] split over `threads` scoped threads (0: one per
    /// core), for an engine without a job system of its own; one that has one calls
    /// [`Palette::compute_batch_with_ups`] from its workers on disjoint ranges instead (this
    /// spawns threads, which allocates).
    pub fn compute_batch_parallel(
        &self,
        bones: &[Affine],
        ups: &[[f32; 3]],
        out: &mut [Affine],
        threads: usize,
    ) -> Result<()> {
        let c = self.characters(bones, out)?;
        check_character_ups(c, ups)?;
        let threads = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        }
        .min(c.max(1));
        if threads <= 1 {
            return self.compute_batch_with_ups(bones, ups, out);
        }
        let per = c.div_ceil(threads);
        let j = self.model.bone_count();
        std::thread::scope(|s| {
            let work = bones.chunks(per * j).zip(out.chunks_mut(per * self.len()));
            let handles: Vec<_> = (work.enumerate())
                .map(|(k, (q, o))| {
                    let ups = ups
                        .get(k * per..ups.len().min((k + 1) * per))
                        .unwrap_or(&[]);
                    s.spawn(move || self.compute_batch_with_ups(q, ups, o))
                })
                .collect();
            handles.into_iter().try_for_each(|h| {
                h.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
        })
    }

    /// The vertices an engine's skinning makes of one character's palette and corrective
    /// weights ([`Palette::corrective_weights`]: N, empty for a model without correctives):
    /// `positions` V, each `Σ_k w_k M_{i_k} [x̂ + Σ_n weights[n] target_n; 1]`. Allocates
    /// nothing.
    pub fn skin_positions(
        &self,
        palette: &[Affine],
        weights: &[f32],
        positions: &mut [[f32; 3]],
    ) -> Result<()> {
        let skin = self.skin();
        let n = skin.correctives;
        for (what, expected, actual) in [
            ("palette transforms", self.len(), palette.len()),
            ("positions", skin.rest_positions.len(), positions.len()),
            ("corrective weights", n, weights.len()),
        ] {
            if expected != actual {
                return Err(Error::WrongLength {
                    what,
                    expected,
                    actual,
                });
            }
        }
        let v = skin.rest_positions.len();
        for (a, out) in positions.iter_mut().enumerate() {
            let m = skin.blended(a, palette);
            let mut rest = skin.rest_positions[a];
            for (t, &w) in weights.iter().enumerate() {
                let delta = skin.corrective_targets[t * v + a];
                rest.iter_mut().zip(delta).for_each(|(x, d)| *x += w * d);
            }
            let [x, y, z] = rest;
            *out = [0, 4, 8].map(|r| m[r] * x + m[r + 1] * y + m[r + 2] * z + m[r + 3]);
        }
        Ok(())
    }

    /// C, after checking the lengths and that the bones are finite (bones first).
    fn characters(&self, bones: &[Affine], out: &[Affine]) -> Result<usize> {
        let c = characters(bones, self.model.bone_count())?;
        if out.len() != c * self.len() {
            return Err(Error::WrongLength {
                what: "palette transforms (characters x (proxies + bones))",
                expected: c * self.len(),
                actual: out.len(),
            });
        }
        Ok(c)
    }

    /// One character's palette `out` from its bones `q` and its up (None: the model's).
    fn character(&self, q: &[Affine], up: Option<Vec3>, out: &mut [Affine], scratch: &mut Scratch) {
        let (p, j) = (self.model.proxy_count(), self.model.bone_count());
        scratch.theta.resize(j, Vec3::ZERO);
        scratch.rhs.resize(3 * p + 4 * j, Vec3::ZERO);
        let rotation = |b: usize| rotation_of(&q[b]);
        for &b in &self.rotations {
            let b = b as usize;
            scratch.theta[b] = match self.model.parent(b) {
                Some(parent) => log_rotation(rotation(parent).transpose() * rotation(b)),
                None => log_rotation(rotation(b)),
            };
        }
        for k in &self.predictors {
            let d = k.gradient(&scratch.theta, rotation);
            scratch.rhs[3 * k.key..3 * k.key + 3].copy_from_slice(&[d.x_axis, d.y_axis, d.z_axis]);
        }
        self.delta_mush_gradients(q, &mut scratch.rhs);
        for (b, t) in q.iter().enumerate() {
            for k in 0..4 {
                scratch.rhs[3 * p + 4 * b + k] = Vec3::new(t[k], t[4 + k], t[8 + k]);
            }
        }
        for (e, t) in out[..p].iter_mut().enumerate() {
            let (columns, values) = self.blocks.of_proxy(e);
            let mut acc = [[0.0f32; 4]; 3];
            for (&k, v) in columns.iter().zip(values) {
                let x = scratch.rhs[k as usize];
                for (row, xc) in acc.iter_mut().zip([x.x, x.y, x.z]) {
                    row.iter_mut().zip(v).for_each(|(a, v)| *a += v * xc);
                }
            }
            *t = bytemuck::cast(acc);
        }
        self.proxy.features(q, up, &mut scratch.features);
        self.proxy.correct(&scratch.features, &mut out[..p]);
        out[p..].copy_from_slice(q);
    }
}

/// The bones whose rotation relative to their parent (θ~_b) a character's predictors read: each
/// key's bone, its parent and its second bone, ascending.
pub(crate) fn rotation_bones(model: &Model) -> Vec<u32> {
    let mut read = vec![false; model.bone_count()];
    for k in model.keys().iter().filter_map(Key::predictor) {
        let (bone, second) = (k.bone as usize, k.second.as_ref().map(|s| s.bone as usize));
        for b in [Some(bone), model.parent(bone), second]
            .into_iter()
            .flatten()
        {
            read[b] = true;
        }
    }
    (0..read.len() as u32)
        .filter(|&b| read[b as usize])
        .collect()
}

impl Palette {
    /// Every delta-mush key's gradient `D_ℓ = fit(A_ℓ)` for one character's bones `q`, as
    /// three columns each into `rhs` (at 3ℓ), [`DELTA_MUSH_LANES`] keys at a time: one key's
    /// rotation fit is a chain of dependent steps, which lanes pay once for all of them
    /// ([`nearest_rotations_f32`]).
    fn delta_mush_gradients(&self, q: &[Affine], rhs: &mut [Vec3]) {
        let keys = self.model.keys();
        for chunk in self.delta_mush.chunks(DELTA_MUSH_LANES) {
            // The last chunk's unused lanes fit A = 0 (the identity), and are dropped.
            let a: [[[f32; 3]; 3]; DELTA_MUSH_LANES] =
                std::array::from_fn(|i| match chunk.get(i).and_then(|&l| keys[l].delta_mush()) {
                    Some(key) => delta_mush_covariance_f32(key, q),
                    None => [[0.0; 3]; 3],
                });
            for (r, &l) in nearest_rotations_f32(&a).iter().zip(chunk) {
                for (c, column) in rhs[3 * l..3 * l + 3].iter_mut().enumerate() {
                    *column = Vec3::new(r[0][c], r[1][c], r[2][c]);
                }
            }
        }
    }
}

/// How many delta-mush keys the CPU palette fits side by side: 8 `f32` lanes fill two SSE
/// registers or one AVX register per value.
const DELTA_MUSH_LANES: usize = 8;

/// The features `φ = vec(R − I)`, `R = rot(Q_p)ᵀ rot(Q_b)`, row-major, of both correctives in
/// `f32` ([`crate::predict::rotation_features`] in f64): `R[r][c] = Σ_k Q_p[k][r] Q_b[k][c]`
/// (row-major 3x4 transforms).
fn phi_f32(qp: &Affine, qb: &Affine) -> [f32; 9] {
    std::array::from_fn(|e| {
        let (r, c) = (e / 3, e % 3);
        let dot: f32 = (0..3).map(|k| qp[4 * k + r] * qb[4 * k + c]).sum();
        dot - f32::from(u8::from(r == c))
    })
}

impl ProxyTerms {
    /// Compiles `c`, the proxy correctives of `model` (validated: drivers have parents, widths
    /// cover the drivers when C > 0, each map has `D_i F` rows of 12).
    fn new(model: &Model, c: &ProxyCorrectives) -> ProxyTerms {
        let j = model.bone_count();
        let kernels = c.kernel_count(j);
        let mut bones = c.drivers.clone();
        bones.sort_unstable();
        bones.dedup();
        let drivers: Vec<(usize, usize)> = (bones.iter())
            .map(|&b| (b as usize, model.parent(b as usize).unwrap_or(b as usize)))
            .collect();
        let f = c.features_per_driver(j);
        let index = (c.drivers.iter())
            .map(|b| bones.partition_point(|x| x < b))
            .flat_map(|s| (s * f..(s + 1) * f).map(|x| x as u32))
            .collect();
        let centres: Vec<[f32; 9]> = (drivers.iter())
            .flat_map(|&(b, _)| (0..kernels).map(move |k| c.centres[k * j + b]))
            .collect();
        let widths: Vec<f32> = if kernels > 0 {
            drivers.iter().map(|&(b, _)| c.widths[b]).collect()
        } else {
            Vec::new()
        };
        let at_rest = (centres.iter().enumerate())
            .map(|(k, z)| kernel(&[0.0; 9], z, widths[k / kernels]))
            .collect();
        let ranges = match c.ranges.is_empty() {
            true => Vec::new(),
            false => drivers.iter().map(|&(b, _)| c.ranges[b]).collect(),
        };
        ProxyTerms {
            ranges,
            drivers,
            features: f,
            linear: c.linear,
            up: c.up.map(Vec3::from),
            centres,
            widths,
            at_rest,
            proxies: c.proxies.clone(),
            offsets: c.driver_offsets.iter().map(|&k| k * f as u32).collect(),
            rows: (c.maps.chunks_exact(12))
                .map(|g| std::array::from_fn(|k| g[k]))
                .collect(),
            index,
        }
    }

    /// The features of one character's J bones `q` and its `up` (None: the model's) into `x:
    /// (D x F)`: per driver slot, φ_b (if linear), `γ_b = rot(Q_b)ᵀ u_c − u` (if the model has
    /// an up u), then `exp(−|φ_b − z_c|² / w_b) − exp(−|z_c|² / w_b)` for its C kernels; φ_b and
    /// γ_b clamped into the slot's range where the model has ranges.
    fn features(&self, q: &[Affine], up: Option<Vec3>, x: &mut Vec<f32>) {
        let (linear, gravity) = (
            9 * usize::from(self.linear),
            3 * usize::from(self.up.is_some()),
        );
        let (f, kernels) = (self.features, self.features - linear - gravity);
        x.resize(self.drivers.len() * f, 0.0);
        for (s, &(b, p)) in self.drivers.iter().enumerate() {
            let range = self.ranges.get(s);
            let mut phi = phi_f32(&q[p], &q[b]);
            if let Some(r) = range {
                r.clamp(&mut phi, 0);
            }
            let (head, x) = x[s * f..(s + 1) * f].split_at_mut(f - kernels);
            head[..linear].copy_from_slice(&phi[..linear]);
            if let Some(u) = self.up {
                let mut gamma = (rotation_of(&q[b]).transpose() * up.unwrap_or(u) - u).to_array();
                if let Some(r) = range {
                    r.clamp(&mut gamma, 9);
                }
                head[linear..].copy_from_slice(&gamma);
            }
            for (c, x) in x.iter_mut().enumerate() {
                let k = s * kernels + c;
                *x = kernel(&phi, &self.centres[k], self.widths[s]) - self.at_rest[k];
            }
        }
    }

    /// Corrects one character's P proxies `out` in place, `T'_e = T_e (I + E_e)`, from its
    /// features `x: (D x F)` ([`ProxyTerms::features`]). Rows alternate between two sums (the
    /// adds of one do not wait on the other's).
    fn correct(&self, x: &[f32], out: &mut [Affine]) {
        for (i, &e) in self.proxies.iter().enumerate() {
            let range = self.offsets[i] as usize..self.offsets[i + 1] as usize;
            let (rows, index) = (&self.rows[range.clone()], &self.index[range]);
            let (mut even, mut odd) = ([0.0f32; 12], [0.0f32; 12]);
            let pairs = rows.len() / 2 * 2;
            for (g, k) in rows[..pairs].chunks_exact(2).zip(index.chunks_exact(2)) {
                axpy(&mut even, x[k[0] as usize], &g[0]);
                axpy(&mut odd, x[k[1] as usize], &g[1]);
            }
            if let (Some(g), Some(&k)) = (rows.get(pairs), index.get(pairs)) {
                axpy(&mut even, x[k as usize], g);
            }
            even.iter_mut().zip(odd).for_each(|(e, o)| *e += o);
            let t = &mut out[e as usize];
            *t = corrected(t, &even);
        }
    }
}

/// `g += x row` for 3x4 row-major `g` and `row`.
fn axpy(g: &mut [f32; 12], x: f32, row: &[f32; 12]) {
    g.iter_mut().zip(row).for_each(|(g, r)| *g += x * r);
}

/// `exp(−|φ − z|² / w)`, one term of [`crate::predict::kernel_feature`] in `f32`.
fn kernel(phi: &[f32; 9], z: &[f32; 9], w: f32) -> f32 {
    let d2: f32 = phi.iter().zip(z).map(|(f, z)| (f - z) * (f - z)).sum();
    (-d2 / w).exp()
}

/// `T (I + E)` for 3x4 row-major `T = [M | t]` and `E = [A | b]`: `[M + M A | t + M b]`
/// ([`crate::predict::corrected`] in `f32`).
fn corrected(t: &Affine, e: &Affine) -> Affine {
    std::array::from_fn(|i| {
        let (r, c) = (i / 4, i % 4);
        t[i] + t[4 * r] * e[c] + t[4 * r + 1] * e[4 + c] + t[4 * r + 2] * e[8 + c]
    })
}

impl CompiledPredictor {
    fn new(model: &Model, key: usize, k: &KeyPredictor) -> CompiledPredictor {
        CompiledPredictor {
            key,
            bone: k.bone as usize,
            parent: model.parent(k.bone as usize),
            uw: mat3(&k.w) * k.u,
            second: (k.second.as_ref()).map(|s| (s.bone as usize, mat3(&s.w) * s.u)),
            h: k.h,
        }
    }

    /// `D_ℓ(q) = R(q) S(q)`, mirroring [`crate::predict::predictor_gradient`] in `f32`.
    fn gradient(&self, theta: &[Vec3], rotation: impl Fn(usize) -> Mat3) -> Mat3 {
        let t = theta[self.bone];
        let (q_parent, t_parent) = match self.parent {
            Some(p) => (rotation(p), theta[p]),
            None => (Mat3::IDENTITY, Vec3::ZERO),
        };
        let mut r = q_parent * exp_rotation(self.uw * t);
        if let Some((b, uw)) = self.second {
            r *= exp_rotation(uw * theta[b]);
        }
        let x = [t.x, t.y, t.z, t_parent.x, t_parent.y, t_parent.z, 1.0];
        let s: [f32; 9] = std::array::from_fn(|i| (0..7).map(|j| self.h[7 * i + j] * x[j]).sum());
        r * Mat3::from_cols_array(&s).transpose()
    }
}

fn mat3(rows: &[f32; 9]) -> Mat3 {
    Mat3::from_cols_array(rows).transpose()
}

fn rotation_of(t: &Affine) -> Mat3 {
    Mat3::from_cols(
        Vec3::new(t[0], t[4], t[8]),
        Vec3::new(t[1], t[5], t[9]),
        Vec3::new(t[2], t[6], t[10]),
    )
}
