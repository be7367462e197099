//! CPU reference evaluator of the whole per-frame pipeline (paper §6, docs/method.md §9), in `f64`:
//! the oracle every GPU test compares against.
//!
//! Per character: (1) key gradients `d = D_ℓ(q)` (predictors', then delta-mush keys'); (2) proxy transforms `t_c = C1 d_c + C2 q_c`
//! for c = x, y, z (Eq. 5 in the separable form of docs/method.md §8); (3) palette skinning over
//! `[t (P); q (J)]` with K influences; (4) normals as [`NormalMode`] says (`crate::normals`):
//! recomputed, the area-weighted sum of incident triangle normals, normalised (zero where the sum
//! vanishes), or transformed, the rest normal through the cofactor of the blended matrix; (5) with [`CpuEvaluator::evaluate_with_tangents`],
//! tangents: the rest tangent through the blended palette matrix's 3x3, made orthogonal to the
//! normal and normalised (zero where it vanishes), w kept. With pose-space correctives
//! (paper §8), step (3) skins `ŷ_a + Σ_n w_n targets[n V + a]`, `w` =
//! [`crate::predict::corrective_weights`] of the character's bones. With proxy correctives
//! (docs/method.md §21), between (2) and (3) each corrected proxy becomes `T_e (I + E_e)`
//! ([`crate::predict::apply_proxy_correctives`]), from each character's up vector where they see
//! gravity ([`CpuEvaluator::set_ups`]; the model's up by default).

use crate::error::{Error, Result};
use crate::model::Model;
use crate::normals::{area_weighted_sums, cofactor_times, NormalMode};
use crate::predict::{apply_proxy_correctives, corrective_weights, key_gradients, Affine};
use glam::{DMat3, DVec3};

/// Evaluates C characters of one model. Holds its scratch, so repeated frames allocate nothing.
pub struct CpuEvaluator<'m> {
    model: &'m Model,
    normals: NormalMode,
    /// The model's rest normals where normals are transformed (else empty).
    rest_normals: Vec<DVec3>,
    /// The area normals summed per normal group (V), where normals are recomputed.
    normal_sums: Vec<DVec3>,
    /// `[C1 | C2]`, 4P x (3P + 4J), row-major.
    c1_c2: Vec<f64>,
    /// Right-hand side of the GEMM for one character and coordinate: `[d_c; q_c]`, 3P + 4J.
    rhs: Vec<f64>,
    /// Palette of one character: P + J transforms, 3x4 row-major.
    palette: Vec<[f64; 12]>,
    gradients: Vec<DMat3>,
    /// The corrective weights of one character (N).
    weights: Vec<f64>,
    /// Each character's up vector ([`CpuEvaluator::set_ups`]), or empty: the model's.
    ups: Vec<[f32; 3]>,
    positions: Vec<DVec3>,
}

impl<'m> CpuEvaluator<'m> {
    /// Normals recomputed from the skinned positions ([`NormalMode::Recomputed`]).
    pub fn new(model: &'m Model) -> Self {
        Self::with_normals(model, NormalMode::Recomputed)
    }

    /// Normals made as `mode` says (and so the tangents, orthogonal to them).
    pub fn with_normals(model: &'m Model, mode: NormalMode) -> Self {
        let (p, j) = (model.proxy_count(), model.bone_count());
        let rest_normals = match mode {
            NormalMode::Recomputed => Vec::new(),
            NormalMode::Transformed => (model.rest_normals().iter())
                .map(|n| DVec3::from(n.map(f64::from)))
                .collect(),
        };
        CpuEvaluator {
            model,
            normals: mode,
            rest_normals,
            normal_sums: Vec::new(),
            c1_c2: model.c1_c2().into_iter().map(f64::from).collect(),
            rhs: vec![0.0; 3 * p + 4 * j],
            palette: vec![[0.0; 12]; p + j],
            gradients: vec![DMat3::ZERO; p],
            weights: vec![0.0; model.corrective_count()],
            ups: Vec::new(),
            positions: vec![DVec3::ZERO; model.vertex_count()],
        }
    }

    /// Each character's up vector in its bones' frame for the evaluations that follow (C of
    /// them, checked when evaluating), or none: the model's up ([`Model::up`]). Only models whose
    /// proxy correctives see gravity read it.
    pub fn set_ups(&mut self, ups: &[[f32; 3]]) -> Result<()> {
        crate::predict::check_ups(ups)?;
        self.ups = ups.to_vec();
        Ok(())
    }

    /// `bones`: C x J transforms. `positions`, `normals`: C x V, written.
    pub fn evaluate(
        &mut self,
        bones: &[Affine],
        positions: &mut [[f32; 3]],
        normals: &mut [[f32; 3]],
    ) -> Result<()> {
        self.evaluate_outputs(bones, positions, normals, None)
    }

    /// [`CpuEvaluator::evaluate`], and `tangents` (C x V, xyz and handedness w) written too:
    /// `NotInModel` for a model without rest tangents.
    pub fn evaluate_with_tangents(
        &mut self,
        bones: &[Affine],
        positions: &mut [[f32; 3]],
        normals: &mut [[f32; 3]],
        tangents: &mut [[f32; 4]],
    ) -> Result<()> {
        if !self.model.has_tangents() {
            return Err(Error::NotInModel {
                what: "rest tangents",
            });
        }
        self.evaluate_outputs(bones, positions, normals, Some(tangents))
    }

    fn evaluate_outputs(
        &mut self,
        bones: &[Affine],
        positions: &mut [[f32; 3]],
        normals: &mut [[f32; 3]],
        mut tangents: Option<&mut [[f32; 4]]>,
    ) -> Result<()> {
        let (v, j) = (self.model.vertex_count(), self.model.bone_count());
        let c = characters(bones, j)?;
        for (what, out) in [("positions", &*positions), ("normals", &*normals)] {
            if out.len() != c * v {
                return Err(Error::WrongLength {
                    what,
                    expected: c * v,
                    actual: out.len(),
                });
            }
        }
        crate::predict::check_character_ups(c, &self.ups)?;
        if let Some(t) = tangents.as_deref() {
            if t.len() != c * v {
                return Err(Error::WrongLength {
                    what: "tangents",
                    expected: c * v,
                    actual: t.len(),
                });
            }
        }
        for ch in 0..c {
            let q = &bones[ch * j..(ch + 1) * j];
            self.corrected_palette_of(q, self.ups.get(ch).copied())?;
            corrective_weights(self.model, q, &mut self.weights)?;
            self.skin();
            let normals = &mut normals[ch * v..(ch + 1) * v];
            self.normals_into(normals);
            if let Some(t) = tangents.as_deref_mut() {
                self.tangents_into(normals, &mut t[ch * v..(ch + 1) * v]);
            }
            for (out, p) in positions[ch * v..(ch + 1) * v]
                .iter_mut()
                .zip(&self.positions)
            {
                *out = p.as_vec3().to_array();
            }
        }
        Ok(())
    }

    /// One character's intermediates as the GPU passes hold them (`q`: its J bone
    /// transforms): the key gradients `D_ℓ(q)` of pass 1 (P), and the palette
    /// `[T' (P); q (J)]` (3x4 row-major) after the product and the proxy correctives (with the
    /// first up vector set, if any).
    pub fn intermediates(&mut self, q: &[Affine]) -> Result<(&[DMat3], &[[f64; 12]])> {
        let j = self.model.bone_count();
        if characters(q, j)? != 1 {
            return Err(Error::WrongLength {
                what: "bone transforms (one character)",
                expected: j,
                actual: q.len(),
            });
        }
        self.corrected_palette_of(q, self.ups.first().copied())?;
        Ok((&self.gradients, &self.palette))
    }

    /// The palette of one character with its proxies corrected (`T_e (I + E_e)`).
    fn corrected_palette_of(&mut self, q: &[Affine], up: Option<[f32; 3]>) -> Result<()> {
        self.palette_of(q);
        let p = self.model.proxy_count();
        apply_proxy_correctives(self.model, q, up, &mut self.palette[..p])
    }

    /// The P + J palette of one character: proxies by Eq. 5, then the bones themselves.
    fn palette_of(&mut self, q: &[Affine]) {
        let model = self.model;
        let (p, j) = (model.proxy_count(), model.bone_count());
        key_gradients(model, q, &mut self.gradients);
        let width = 3 * p + 4 * j;
        for c in 0..3 {
            for (l, g) in self.gradients.iter().enumerate() {
                let row = g.row(c);
                self.rhs[3 * l..3 * l + 3].copy_from_slice(&row.to_array());
            }
            for (b, t) in q.iter().enumerate() {
                for k in 0..4 {
                    self.rhs[3 * p + 4 * b + k] = t[4 * c + k] as f64;
                }
            }
            for r in 0..4 * p {
                let a = &self.c1_c2[r * width..(r + 1) * width];
                self.palette[r / 4][4 * c + r % 4] =
                    a.iter().zip(&self.rhs).map(|(x, y)| x * y).sum();
            }
        }
        for (slot, t) in self.palette[p..].iter_mut().zip(q) {
            *slot = t.map(f64::from);
        }
    }

    /// Vertex `a`'s blended palette matrix, 3x4 row-major.
    fn blended(&self, a: usize) -> [f64; 12] {
        let parts = self.model.parts();
        let k = self.model.influences();
        let mut m = [0.0f64; 12];
        for i in a * k..(a + 1) * k {
            let w = parts.skin_weights[i] as f64;
            let entry = &self.palette[parts.skin_indices[i] as usize];
            m.iter_mut().zip(entry).for_each(|(x, e)| *x += w * e);
        }
        m
    }

    fn skin(&mut self) {
        let parts = self.model.parts();
        let v = self.positions.len();
        let targets = parts.correctives.as_ref().map_or(&[][..], |c| &c.targets);
        for a in 0..v {
            let mut rest = DVec3::from(parts.rest_positions[a].map(f64::from));
            for (n, &w) in self.weights.iter().enumerate() {
                rest += w * DVec3::from(targets[n * v + a].map(f64::from));
            }
            let m = self.blended(a);
            self.positions[a] = DVec3::new(
                m[0] * rest.x + m[1] * rest.y + m[2] * rest.z + m[3],
                m[4] * rest.x + m[5] * rest.y + m[6] * rest.z + m[7],
                m[8] * rest.x + m[9] * rest.y + m[10] * rest.z + m[11],
            );
        }
    }

    fn tangents_into(&self, normals: &[[f32; 3]], out: &mut [[f32; 4]]) {
        let rest = &self.model.parts().rest_tangents;
        for (a, (t, n)) in out.iter_mut().zip(normals).enumerate() {
            let m = self.blended(a);
            let [x, y, z, w] = rest[a].map(f64::from);
            let skinned = DVec3::new(
                m[0] * x + m[1] * y + m[2] * z,
                m[4] * x + m[5] * y + m[6] * z,
                m[8] * x + m[9] * y + m[10] * z,
            );
            let n = DVec3::from(n.map(f64::from));
            let s = skinned - n * n.dot(skinned);
            let len = s.length();
            let s = if len > 0.0 { s / len } else { DVec3::ZERO };
            *t = [s.x as f32, s.y as f32, s.z as f32, w as f32];
        }
    }

    fn normals_into(&mut self, out: &mut [[f32; 3]]) {
        let model = self.model;
        let normal = |n: DVec3| n.normalize_or_zero().as_vec3().to_array();
        match self.normals {
            NormalMode::Recomputed => {
                let group = |v| model.normal_group(v);
                let sums = &mut self.normal_sums;
                area_weighted_sums(&self.positions, model.triangle_corners(), group, sums);
                for (a, n) in out.iter_mut().enumerate() {
                    *n = normal(self.normal_sums[group(a)]);
                }
            }
            NormalMode::Transformed => {
                for (a, n) in out.iter_mut().enumerate() {
                    *n = normal(cofactor_times(&self.blended(a), self.rest_normals[a]));
                }
            }
        }
    }
}

/// The median of `values` (of an even count, the upper of the two middle values; NaN sorts
/// last), or `None` if there are none. Timings and sample spacings use it.
pub fn median(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let mut sorted: Vec<f64> = values.into_iter().collect();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied()
}

/// C of C x J bone transforms, checked: whole characters, every number finite.
pub(crate) fn characters(bones: &[Affine], j: usize) -> Result<usize> {
    if bones.len() % j != 0 {
        return Err(Error::WrongLength {
            what: "bone transforms (characters x bones)",
            expected: bones.len().div_ceil(j) * j,
            actual: bones.len(),
        });
    }
    check_finite(bones)?;
    Ok(bones.len() / j)
}

/// Per-frame input must be finite: one NaN would spread through C1/C2 to a whole character.
pub(crate) fn check_finite(bones: &[Affine]) -> Result<()> {
    match bones.as_flattened().iter().position(|x| !x.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: "bone transforms",
            index,
        }),
        None => Ok(()),
    }
}
