//! Key-predictor evaluation `D_ℓ(q)` (paper §3, Eq. 3–4; docs/method.md §2–3) and the rotation
//! math it needs, in `f64`. `glsl/key.glsl` mirrors these functions line for line in `f32`
//! (same branch thresholds), so the two agree away from the rotation log's branch cut at π.

use crate::error::{Error, Result};
use crate::model::{DeltaMushKey, Key, KeyPredictor, Mat3Rows, Model};
use glam::{DMat3, DVec3, Mat3, Vec3};

/// A bone transform relative to the rest pose, 3x4 row-major: `x ↦ Q x + d`.
pub type Affine = [f32; 12];

/// Below this `sin θ` with `cos θ < 0`, `log` takes the axis from the symmetric part of R
/// (the antisymmetric part vanishes at π). Shared with `glsl/key.glsl`.
pub const NEAR_PI_SIN: f64 = 1e-2;
/// Below this angle, `log` and `exp` use Taylor series. Shared with `glsl/key.glsl`.
pub const SMALL_ANGLE: f64 = 1e-4;

/// The rotation part Q of a bone transform.
pub fn rotation_of(t: &Affine) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(t[0] as f64, t[4] as f64, t[8] as f64),
        DVec3::new(t[1] as f64, t[5] as f64, t[9] as f64),
        DVec3::new(t[2] as f64, t[6] as f64, t[10] as f64),
    )
}

/// A row-major 3x3 as a glam matrix.
pub fn mat3_of_rows(w: &Mat3Rows) -> DMat3 {
    DMat3::from_cols_array(&w.map(|x| x as f64)).transpose()
}

/// `log: SO(3) → R³` in one body for `f64` (the CPU reference, training) and `f32` (the CPU
/// palette), with the branches and thresholds of `glsl/key.glsl`.
macro_rules! rotation_log {
    ($log:ident, $mat:ident, $vec:ident, $f:ty) => {
        /// `log: SO(3) → R³`, the axis-angle vector with angle in [0, π].
        pub fn $log(r: $mat) -> $vec {
            let (c0, c1, c2) = (r.x_axis, r.y_axis, r.z_axis);
            // vee(R − Rᵀ) = 2 sin θ · axis
            let v = $vec::new(c1.z - c2.y, c2.x - c0.z, c0.y - c1.x);
            let s = 0.5 * v.length();
            let c = 0.5 * (c0.x + c1.y + c2.z - 1.0);
            let angle = s.atan2(c);
            if angle < SMALL_ANGLE as $f {
                return v * (0.5 * (1.0 + angle * angle / 6.0));
            }
            if s < NEAR_PI_SIN as $f && c < 0.0 {
                // (R + Rᵀ)/2 − cos θ I = (1 − cos θ) a aᵀ: the axis from its column with the
                // largest diagonal, oriented like the (tiny) antisymmetric part.
                let sym = (r + r.transpose()) * 0.5 - $mat::from_diagonal($vec::splat(c));
                let b = [sym.x_axis, sym.y_axis, sym.z_axis];
                let i = if b[0].x >= b[1].y && b[0].x >= b[2].z {
                    0
                } else if b[1].y >= b[2].z {
                    1
                } else {
                    2
                };
                let axis = b[i].normalize();
                return if axis.dot(v) < 0.0 { -axis } else { axis } * angle;
            }
            v * (angle / (2.0 * s))
        }
    };
}

rotation_log!(log_rotation, DMat3, DVec3, f64);
rotation_log!(log_rotation_f32, Mat3, Vec3, f32);

/// `sin θ/θ` and `(1 − cos θ)/θ²` of `exp` for `θ² = a2`, by Taylor series below
/// [`SMALL_ANGLE`].
macro_rules! exp_coefficients {
    ($a2:expr, $f:ty) => {{
        let a2 = $a2;
        let a = a2.sqrt();
        if a < SMALL_ANGLE as $f {
            (1.0 - a2 / 6.0, 0.5 - a2 / 24.0)
        } else {
            let (sin, cos) = a.sin_cos();
            (sin / a, (1.0 - cos) / a2)
        }
    }};
}

/// `exp: R³ → SO(3)` (Rodrigues), `I + sin θ/θ K + (1 − cos θ)/θ² K²` with `K = [w]ₓ`: the form
/// the models were trained with (an algebraically equal form moves their bytes by round-off).
pub fn exp_rotation(w: DVec3) -> DMat3 {
    let (s, c) = exp_coefficients!(w.length_squared(), f64);
    let k = DMat3::from_cols(
        DVec3::new(0.0, w.z, -w.y),
        DVec3::new(-w.z, 0.0, w.x),
        DVec3::new(w.y, -w.x, 0.0),
    );
    DMat3::IDENTITY + k * s + k * k * c
}

/// [`exp_rotation`] in `f32` for the CPU palette, in the closed form `cos θ I + sin θ/θ [w]ₓ +
/// (1 − cos θ)/θ² w wᵀ` (no matrix product `K²`: the palette evaluates one a key per frame).
pub fn exp_rotation_f32(w: Vec3) -> Mat3 {
    let a2 = w.length_squared();
    let (s, c) = exp_coefficients!(a2, f32);
    let cos = 1.0 - c * a2;
    let (sw, cw) = (w * s, w * c);
    Mat3::from_cols(
        Vec3::new(cos + cw.x * w.x, sw.z + cw.x * w.y, -sw.y + cw.x * w.z),
        Vec3::new(-sw.z + cw.y * w.x, cos + cw.y * w.y, sw.x + cw.y * w.z),
        Vec3::new(sw.y + cw.z * w.x, -sw.x + cw.z * w.y, cos + cw.z * w.z),
    )
}

/// Joint rotation of bone b in rest-world coordinates: `θ~_b = log(Q_p(b)ᵀ Q_b)` (docs/method.md
/// §0), `log Q_b` for a root. `bones`: the J transforms of one character.
pub fn joint_rotation(model: &Model, bones: &[Affine], b: usize) -> DVec3 {
    let q = rotation_of(&bones[b]);
    match model.parent(b) {
        Some(p) => log_rotation(rotation_of(&bones[p]).transpose() * q),
        None => log_rotation(q),
    }
}

/// `φ = vec(R − I)` of bone `b` relative to bone `p` (its parent), row-major: `φ[3r + c] =
/// R[r][c] − δ_rc` with `R = rot(Q_p)ᵀ rot(Q_b)`: the features of the pose-space correctives and
/// the linear features of the proxy correctives. Exactly zero when both are the identity.
pub fn rotation_features(bones: &[Affine], b: usize, p: usize) -> [f64; 9] {
    let r = rotation_of(&bones[p]).transpose() * rotation_of(&bones[b]);
    // R[r][c] is column c's component r in glam.
    std::array::from_fn(|k| {
        let (row, col) = (k / 3, k % 3);
        r.col(col)[row] - f64::from(u8::from(row == col))
    })
}

/// The pose-space corrective weights of one character (`bones`: its J transforms), `w = map ·
/// φ(q)` with `φ[9i + 3r + c] = R_i[r][c] − δ_rc` and `R_i = rot(Q_p)ᵀ rot(Q_d)` for driver i
/// (bone d, parent p): `out` N (empty without correctives). `WrongLength` unless `bones` is J
/// and `out` N.
pub fn corrective_weights(model: &Model, bones: &[Affine], out: &mut [f64]) -> Result<()> {
    for (what, expected, actual) in [
        ("bone transforms", model.bone_count(), bones.len()),
        ("corrective weights", model.corrective_count(), out.len()),
    ] {
        if expected != actual {
            return Err(Error::WrongLength {
                what,
                expected,
                actual,
            });
        }
    }
    let Some(c) = model.correctives() else {
        return Ok(());
    };
    out.fill(0.0);
    let width = 9 * c.drivers.len();
    for (i, &d) in c.drivers.iter().enumerate() {
        let d = d as usize;
        let p = model.parent(d).unwrap_or(d); // validated: drivers have parents
        let phi = rotation_features(bones, d, p);
        for (n, w) in out.iter_mut().enumerate() {
            let map = &c.map[n * width + 9 * i..n * width + 9 * i + 9];
            *w += map
                .iter()
                .zip(&phi)
                .map(|(&m, f)| m as f64 * f)
                .sum::<f64>();
        }
    }
    Ok(())
}

/// The kernel feature of the proxy correctives (docs/method.md §21): `exp(−|φ − z|² / w) −
/// exp(−|z|² / w)`, zero at φ = 0 (both terms are computed alike, so exactly zero there). The
/// centre z as the model stores it (f32) or as training fits it (f64).
pub fn kernel_feature<Z: Copy + Into<f64>>(phi: &[f64; 9], z: &[Z; 9], w: f64) -> f64 {
    let (mut d2, mut r2) = (0.0, 0.0);
    for (&f, &z) in phi.iter().zip(z) {
        let z: f64 = z.into();
        d2 += (f - z) * (f - z);
        r2 += (0.0 - z) * (0.0 - z);
    }
    (-d2 / w).exp() - (-r2 / w).exp()
}

/// The gravity features of a bone (docs/method.md §21): `γ = rot(Q)ᵀ u_c − u`, the character's
/// up `u_c` seen from the bone relative to rest, less the model's up `u`. Zero at the rest pose
/// of an upright character (u_c = u); blind to the heading (a turn about u leaves it).
pub fn gravity_features(bone: &Affine, model_up: [f32; 3], up: [f32; 3]) -> [f64; 3] {
    let (u, uc) = (
        DVec3::from(model_up.map(f64::from)),
        DVec3::from(up.map(f64::from)),
    );
    (rotation_of(bone).transpose() * uc - u).to_array()
}

/// Up vectors a caller gives, each the direction opposite to gravity in the character's bones'
/// frame: finite (`NonFinite` naming the first float that is not). Its length is gravity's
/// strength against the training poses' (γ is linear in it: 0, as in free fall, takes gravity
/// away).
pub fn check_ups(ups: &[[f32; 3]]) -> Result<()> {
    match ups.as_flattened().iter().position(|x| !x.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: "character up vectors",
            index,
        }),
        None => Ok(()),
    }
}

/// `ups` for `characters` characters: one each or none (the model's up), finite
/// ([`check_ups`]).
pub(crate) fn check_character_ups(characters: usize, ups: &[[f32; 3]]) -> Result<()> {
    if !ups.is_empty() && ups.len() != characters {
        return Err(Error::WrongLength {
            what: "character up vectors (characters, or none)",
            expected: characters,
            actual: ups.len(),
        });
    }
    check_ups(ups)
}

/// The correction `E_e = [A | b] = Σ_f x_f G_ef` (3x4 row-major) of corrected proxy i of the
/// model's proxy correctives for one character's J `bones` and its `up` (None: the model's):
/// the features x of its drivers in order, per driver its 9 linear φ_b (if `linear`), its 3
/// gravity features γ_b (if the model has an up), then its C kernels, φ_b and γ_b clamped into
/// the driver's range where the model has ranges (see
/// [`crate::ProxyCorrectives`]). Zero without proxy correctives or at the rest pose of an
/// upright character.
pub fn proxy_correction(
    model: &Model,
    bones: &[Affine],
    up: Option<[f32; 3]>,
    i: usize,
) -> [f64; 12] {
    let mut e = [0.0f64; 12];
    let Some(c) = model.proxy_correctives() else {
        return e;
    };
    let j = model.bone_count();
    let kernels = c.kernel_count(j);
    let mut rows = c.map_of(i, j).chunks_exact(12);
    let mut add = |x: f64, g: &[f32]| {
        e.iter_mut()
            .zip(g)
            .for_each(|(e, &g)| *e += x * f64::from(g));
    };
    for &b in c.drivers_of(i) {
        let b = b as usize;
        let range = c.ranges.get(b);
        let mut phi = rotation_features(bones, b, model.parent(b).unwrap_or(b)); // validated: parents
        if let Some(r) = range {
            r.clamp(&mut phi, 0);
        }
        if c.linear {
            for &x in &phi {
                add(x, rows.next().unwrap_or_default());
            }
        }
        if let Some(u) = c.up {
            let mut gamma = gravity_features(&bones[b], u, up.unwrap_or(u));
            if let Some(r) = range {
                r.clamp(&mut gamma, 9);
            }
            for x in gamma {
                add(x, rows.next().unwrap_or_default());
            }
        }
        for k in 0..kernels {
            let x = kernel_feature(&phi, &c.centres[k * j + b], f64::from(c.widths[b]));
            add(x, rows.next().unwrap_or_default());
        }
    }
    e
}

/// Applies the model's proxy correctives (docs/method.md §21) to one character's proxies: `bones`
/// its J transforms, `up` its up vector in their frame (None: the model's, [`Model::up`]),
/// `proxies` its P proxy transforms `T_e = [M | t]` (3x4 row-major) as
/// computed from C1/C2; each corrected proxy e becomes `T'_e = T_e (I + E_e)` =
/// `[M (I + A) | t + M b]` with `E_e = [A | b]` = [`proxy_correction`]. Nothing changes
/// without proxy correctives. `WrongLength` unless `bones` is J and `proxies` P.
pub fn apply_proxy_correctives(
    model: &Model,
    bones: &[Affine],
    up: Option<[f32; 3]>,
    proxies: &mut [[f64; 12]],
) -> Result<()> {
    for (what, expected, actual) in [
        ("bone transforms", model.bone_count(), bones.len()),
        ("proxy transforms", model.proxy_count(), proxies.len()),
    ] {
        if expected != actual {
            return Err(Error::WrongLength {
                what,
                expected,
                actual,
            });
        }
    }
    let Some(c) = model.proxy_correctives() else {
        return Ok(());
    };
    for (i, &e) in c.proxies.iter().enumerate() {
        let correction = proxy_correction(model, bones, up, i);
        let t = &mut proxies[e as usize];
        *t = corrected(t, &correction);
    }
    Ok(())
}

/// `T (I + E)` for 3x4 row-major affine `T = [M | t]` and `E = [A | b]`: `[M + M A | t + M b]`.
pub fn corrected(t: &[f64; 12], e: &[f64; 12]) -> [f64; 12] {
    let mut out = *t;
    for r in 0..3 {
        for c in 0..4 {
            out[4 * r + c] += (0..3).map(|k| t[4 * r + k] * e[4 * k + c]).sum::<f64>();
        }
    }
    out
}

/// Every key gradient `D_ℓ(q)` of `model` (P) for one character's J bone transforms
/// ([`key_gradient`]).
pub fn key_gradients(model: &Model, bones: &[Affine], out: &mut [DMat3]) {
    for (g, key) in out.iter_mut().zip(model.keys()) {
        *g = key_gradient(model, key, bones);
    }
}

/// `D_ℓ(q)` of one key for one character's J bone transforms: the one dispatch on its kind.
pub fn key_gradient(model: &Model, key: &Key, bones: &[Affine]) -> DMat3 {
    match key {
        Key::Predictor(k) => predictor_gradient(model, k, bones),
        Key::DeltaMush(k) => delta_mush_gradient(k, bones),
    }
}

/// A delta-mush key's rigid fit's covariance in one body for `f64` (the CPU reference, training)
/// and `f32` (the CPU palette), with the order of operations of `glsl/key.glsl`.
macro_rules! delta_mush_covariance {
    ($name:ident, $f:ty) => {
        /// `A(q) = Σ_i [Q_{b_i} | d_{b_i}] Ω_i` (row-major 3x3) of a delta-mush key
        /// ([`crate::DeltaMushKey`]) for one character's J bone transforms: its gradient is
        /// `fit(A)` ([`crate::polar::nearest_rotation`]).
        pub fn $name(key: &DeltaMushKey, bones: &[Affine]) -> [[$f; 3]; 3] {
            let mut a = [[0.0 as $f; 3]; 3];
            for t in &key.terms {
                let m = &bones[t.bone as usize];
                for (r, row) in a.iter_mut().enumerate() {
                    for (c, x) in row.iter_mut().enumerate() {
                        *x += (0..4)
                            .map(|k| <$f>::from(m[4 * r + k]) * <$f>::from(t.omega[3 * k + c]))
                            .sum::<$f>();
                    }
                }
            }
            a
        }
    };
}

delta_mush_covariance!(delta_mush_covariance, f64);
delta_mush_covariance!(delta_mush_covariance_f32, f32);

/// `D(q) = fit(A(q))` of a delta-mush key ([`delta_mush_covariance`]) for one character's J
/// bone transforms.
pub fn delta_mush_gradient(key: &DeltaMushKey, bones: &[Affine]) -> DMat3 {
    let r = crate::polar::nearest_rotation(delta_mush_covariance(key, bones));
    // Rows as columns, transposed.
    DMat3::from_cols_array_2d(&r).transpose()
}

/// `D_ℓ(q) = R(q) S(q)` for one predictor and one character's J bone transforms.
pub fn predictor_gradient(model: &Model, pred: &KeyPredictor, bones: &[Affine]) -> DMat3 {
    let b = pred.bone as usize;
    let theta_b = joint_rotation(model, bones, b);
    let (q_parent, theta_parent) = match model.parent(b) {
        Some(p) => (rotation_of(&bones[p]), joint_rotation(model, bones, p)),
        None => (DMat3::IDENTITY, DVec3::ZERO),
    };
    let mut r = q_parent * exp_rotation(mat3_of_rows(&pred.w) * theta_b * pred.u as f64);
    if let Some(second) = &pred.second {
        let theta2 = joint_rotation(model, bones, second.bone as usize);
        r *= exp_rotation(mat3_of_rows(&second.w) * theta2 * second.u as f64);
    }
    let x = [
        theta_b.x,
        theta_b.y,
        theta_b.z,
        theta_parent.x,
        theta_parent.y,
        theta_parent.z,
        1.0,
    ];
    let mut s_rows = [0.0f64; 9];
    for (i, s) in s_rows.iter_mut().enumerate() {
        *s = (0..7).map(|j| pred.h[7 * i + j] as f64 * x[j]).sum();
    }
    r * DMat3::from_cols_array(&s_rows).transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DMat3, b: DMat3, tol: f64) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() < tol)
    }

    #[test]
    fn log_inverts_exp_across_the_angle_range() {
        let axis = DVec3::new(0.3, -0.5, 0.8).normalize();
        let pi = std::f64::consts::PI;
        for &angle in &[0.0, 1e-7, 1e-3, 0.5, 2.0, 3.0, pi - 2e-3, pi - 3e-6] {
            let w = axis * angle;
            let back = log_rotation(exp_rotation(w));
            assert!(
                (back - w).length() < 1e-8,
                "angle {angle}: {back:?} vs {w:?}"
            );
        }
    }

    #[test]
    fn exp_is_a_rotation() {
        let r = exp_rotation(DVec3::new(1.0, 2.0, -0.5));
        assert!(close(r.transpose() * r, DMat3::IDENTITY, 1e-12));
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }
}
