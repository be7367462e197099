//! Delta-mush keys as the runtime evaluates them (docs/method.md §23): per group of
//! [`DirectDeltaMush::grouped`], the runtime's key ([`rrskin::DeltaMushKey`], its terms in the key's
//! principal frame) and what its proxy adds to it. Training fits the proxies' weights to the
//! function that ships, `D = fit(A') Pᵀ` by [`rrskin::predict::delta_mush_gradient`] (Newton
//! steps from a guess,
//! `rrskin::polar`), not to an exact polar decomposition.

use crate::set::Affine;
use crate::skinning::direct_delta_mush::{DirectDeltaMush, LinearFit};
use glam::{DMat3, DVec3};

/// P delta-mush keys.
#[derive(Clone)]
pub struct Keys {
    /// The runtime's keys, each in its principal frame P_s
    /// ([`rrskin::DeltaMushKey::in_principal_frame`]).
    pub runtime: Vec<rrskin::DeltaMushKey>,
    /// Per key, P_s (row-major): the runtime's fit gives `D_s P_s`.
    frames: Vec<[[f64; 3]; 3]>,
    /// Per key, its group's rigid fit in linear form (the translation's ω_j and centre p);
    /// None for a group without weight, which stays at rest.
    fits: Vec<Option<LinearFit>>,
}

impl Keys {
    /// The keys of the groups of `groups`; a group without weight keeps one zero term, whose
    /// fit is the identity.
    pub fn of(groups: &DirectDeltaMush) -> Keys {
        let fits: Vec<Option<LinearFit>> = (0..groups.entries())
            .map(|g| groups.linear_fit(g))
            .collect();
        let term = |&(b, a, _): &(usize, [[f64; 3]; 4], [f64; 4])| rrskin::DeltaMushTerm {
            bone: b as u32,
            omega: std::array::from_fn(|i| a[i / 3][i % 3] as f32),
        };
        let (runtime, frames) = (fits.iter())
            .map(|fit| {
                let terms = match fit {
                    Some(fit) => fit.terms.iter().map(term).collect(),
                    None => vec![rrskin::DeltaMushTerm {
                        bone: 0,
                        omega: [0.0; 12],
                    }],
                };
                rrskin::DeltaMushKey { terms }.in_principal_frame()
            })
            .unzip();
        Keys {
            runtime,
            frames,
            fits,
        }
    }

    /// P
    pub fn count(&self) -> usize {
        self.fits.len()
    }

    /// The mean bones per key: the run-time cost of the keys.
    pub fn mean_bones(&self) -> f64 {
        let terms: usize = self.runtime.iter().map(|k| k.terms.len()).sum();
        terms as f64 / self.count().max(1) as f64
    }

    /// The frames P_s (row-major) that C1 turns the keys' fits by
    /// ([`rrskin::model::c1_in_key_frames`]).
    pub fn frames(&self) -> &[[[f64; 3]; 3]] {
        &self.frames
    }

    /// Per key, its proxy's transform under `bones` (J): `[D | Σ_j M_j ω_j − D p]`, D the
    /// runtime's fit turned out of the key's frame; the identity for a group without weight.
    pub fn motions(&self, bones: &[Affine]) -> Vec<Affine> {
        let runtime_bones: Vec<_> = bones.iter().map(Affine::to_runtime).collect();
        (self.fits.iter().enumerate())
            .map(|(s, fit)| {
                let Some(fit) = fit else {
                    return Affine {
                        q: DMat3::IDENTITY,
                        d: DVec3::ZERO,
                    };
                };
                let turned = rrskin::predict::delta_mush_gradient(&self.runtime[s], &runtime_bones);
                let frame = DMat3::from_cols_array_2d(&self.frames[s]).transpose();
                let q = turned * frame.transpose();
                let moved: DVec3 = (fit.terms.iter())
                    .map(|(b, _, omega)| {
                        bones[*b].q * DVec3::from_slice(omega) + bones[*b].d * omega[3]
                    })
                    .sum();
                Affine {
                    q,
                    d: moved - q * fit.centre,
                }
            })
            .collect()
    }

    /// C1 (4P x 3P) and C2 (4P x 4J, J = `bones`), row-major, of these keys' proxies in
    /// docs/method.md §8's index convention: proxy g's transform `T_g = [D_g | Σ_j M_j ω_j −
    /// D_g p_g]` takes its key's D through C1 (and −p, its last row) and the ω_j through C2. A
    /// group without weight stays at rest (its D is the identity). The runtime model's C1 also
    /// turns each key's fit out of its frame ([`Keys::frames`]).
    pub fn rows(&self, bones: usize) -> (Vec<f64>, Vec<f64>) {
        let (p, j) = (self.count(), bones);
        let (mut c1, mut c2) = (vec![0.0; 12 * p * p], vec![0.0; 16 * p * j]);
        for (g, fit) in self.fits.iter().enumerate() {
            (0..3).for_each(|k| c1[(4 * g + k) * 3 * p + 3 * g + k] = 1.0);
            let Some(fit) = fit else {
                continue;
            };
            for (b, _, omega) in &fit.terms {
                for (m, w) in omega.iter().enumerate() {
                    c2[(4 * g + 3) * 4 * j + 4 * b + m] = *w;
                }
            }
            for k in 0..3 {
                c1[(4 * g + 3) * 3 * p + 3 * g + k] = -fit.centre[k];
            }
        }
        (c1, c2)
    }
}
