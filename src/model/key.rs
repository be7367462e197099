//! Keys: the P key gradients `D_ℓ(q)` a model's proxies read (paper §3; docs/method.md §2–3,
//! §23), one [`Key`] each, of one [`KeyKind`].
//!
//! A key is one record wherever it lives: the file's KEYS section and the GPU's `Keys` buffer
//! hold the same words ([`key_words`]), and the CPU reference, the CPU palette and
//! `glsl/key.glsl` each dispatch once on the kind. A new kind is a variant here, its record,
//! its gradient in `crate::predict`, `crate::palette` and `glsl/key.glsl`, its checks in
//! `validate` and its cost in `crate::cost` (docs/method.md §25 lists the files).

use crate::error::ModelProblem;

/// Rows of a 3x3 matrix, row-major.
pub type Mat3Rows = [f32; 9];

/// One key: how its gradient `D_ℓ(q)` follows from a character's J bone transforms.
// A predictor is held inline (344 bytes): a model's keys are one Vec built once, and a box per
// predictor would cost every evaluation an indirection.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Key {
    /// `D(q) = R(q) S(q)`, predicted from one or two joints' rotations (paper §3).
    Predictor(KeyPredictor),
    /// `D(q) = fit(Σ_i [Q_{b_i} | d_{b_i}] Ω_i)`, the rotation of a rigid fit of several bones'
    /// motions (docs/method.md §23).
    DeltaMush(DeltaMushKey),
}

/// A key's kind: its record's tag in the file and on the GPU is the discriminant ([`KeyKind::tag`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KeyKind {
    Predictor = 0,
    DeltaMush = 1,
}

impl KeyKind {
    pub const ALL: [KeyKind; 2] = [KeyKind::Predictor, KeyKind::DeltaMush];

    /// The first word of a record of this kind (`glsl/key.glsl`'s `KEY_*`).
    pub fn tag(self) -> u32 {
        self as u32
    }

    /// The kind of tag `tag`, if this build knows it.
    pub fn of_tag(tag: u32) -> Option<KeyKind> {
        KeyKind::ALL.into_iter().find(|k| k.tag() == tag)
    }
}

/// A key predictor (paper §3): `D(q) = R(q) S(q)`.
///
/// Rotation (paper Eq. 3, docs/method.md §2), with p = parent(`bone`) and joint rotations
/// `θ~_b = log(Q_p(b)ᵀ Q_b)` (roots: `log Q_b`):
/// `R₁(q) = Q_p(q) · exp(u W θ~_bone(q))`, and with a second bone
/// `R(q) = R₁(q) · exp(u₂ W₂ θ~_second(q))`.
///
/// Scale/shear (paper Eq. 4, docs/method.md §3): `vec(S) = H x`, `x = [θ~_bone; θ~_p; 1]`
/// (θ~_p = 0 when `bone` is a root), vec stacking the rows of S.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyPredictor {
    pub bone: u32,
    pub u: f32,
    pub w: Mat3Rows,
    pub second: Option<SecondBone>,
    /// H: 9 x 7, row-major.
    pub h: [f32; 63],
}

/// The optional second bone of a rotation predictor (paper §3.2, last paragraph).
#[derive(Debug, Clone, PartialEq)]
pub struct SecondBone {
    pub bone: u32,
    pub u: f32,
    pub w: Mat3Rows,
}

/// The most bones one delta-mush key's fit may read (n): the GPU's key loop runs over them.
pub const MAX_DELTA_MUSH_BONES: usize = 256;

/// A delta-mush key (docs/method.md §23): its gradient is the rotation of a rigid fit of several
/// bones' motions, Direct Delta DeltaMushReport's fit for one group of vertices:
///
/// `D(q) = fit(Σ_i [Q_{b_i} | d_{b_i}] Ω_i)`
///
/// where `[Q | d]` is bone b_i's 3x4 transform, Ω_i is 4x3 (row-major, 12 floats) and `fit(A)`
/// is the rotation [`crate::polar::nearest_rotation`] gives: Newton steps toward the rotation
/// nearest to A (the R maximising tr(Rᵀ A)) from a guess that is exact for a rigid motion where
/// the terms are in the key's principal frame, as training writes them
/// ([`DeltaMushKey::in_principal_frame`]); the identity for A = 0. The key's proxy takes its
/// translation from C1 and C2 as any proxy does (for a group's fit, `t = Σ_i M_i ω_i − D p`),
/// and C1 turns D back out of the key's frame.
///
/// Limits: 1 to [`MAX_DELTA_MUSH_BONES`] terms, of distinct bones.
#[derive(Debug, Clone, PartialEq)]
pub struct DeltaMushKey {
    pub terms: Vec<DeltaMushTerm>,
}

/// One bone's term of a delta-mush key's rigid fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeltaMushTerm {
    /// b_i (< J)
    pub bone: u32,
    /// Ω_i: 4x3 row-major.
    pub omega: [f32; 12],
}

impl DeltaMushKey {
    /// The key's rest covariance `C = Σ_i Ω_i[0..3]` (row-major): its A when every bone is at
    /// rest.
    pub fn rest_covariance(&self) -> [[f64; 3]; 3] {
        let mut c = [[0.0; 3]; 3];
        for t in &self.terms {
            for (k, row) in c.iter_mut().enumerate() {
                row.iter_mut()
                    .enumerate()
                    .for_each(|(m, x)| *x += f64::from(t.omega[3 * k + m]));
            }
        }
        c
    }

    /// This key with its terms in its principal frame, `Ω_i P / λ`
    /// ([`crate::polar::principal_frame`] of [`DeltaMushKey::rest_covariance`]), and the frame
    /// P (a row-major rotation): the fit of the new terms is the key's rotation in its frame,
    /// `D P`, so a proxy reading the key reads `D Pᵀ` ([`c1_in_key_frames`]). A rigid motion of
    /// the key's vertices then makes the fit's guess exact.
    pub fn in_principal_frame(&self) -> (DeltaMushKey, [[f64; 3]; 3]) {
        let (p, scale) = crate::polar::principal_frame(self.rest_covariance());
        let terms = (self.terms.iter())
            .map(|t| {
                let o = t.omega.map(f64::from);
                let omega = std::array::from_fn(|i| {
                    let (k, m) = (i / 3, i % 3);
                    let turned: f64 = (0..3).map(|c| o[3 * k + c] * p[c][m]).sum();
                    (turned / scale) as f32
                });
                DeltaMushTerm { omega, ..*t }
            })
            .collect();
        (DeltaMushKey { terms }, p)
    }
}

impl Key {
    pub fn kind(&self) -> KeyKind {
        match self {
            Key::Predictor(_) => KeyKind::Predictor,
            Key::DeltaMush(_) => KeyKind::DeltaMush,
        }
    }

    /// The key's record: its kind's tag, then its words ([`key_words`]).
    fn record(&self) -> Vec<u32> {
        let mut words = vec![self.kind().tag()];
        match self {
            Key::Predictor(k) => words.extend(predictor_words(k)),
            Key::DeltaMush(k) => {
                for t in &k.terms {
                    words.push(t.bone);
                    words.extend(t.omega.map(f32::to_bits));
                }
            }
        }
        words
    }

    /// The key of `record` (its tag, then its words), if the record is whole.
    fn of_record(record: &[u32]) -> Result<Key, &'static str> {
        let (&tag, words) = record.split_first().ok_or("has no kind")?;
        match KeyKind::of_tag(tag).ok_or("has a kind this build does not know")? {
            KeyKind::Predictor => match <[u32; PREDICTOR_WORDS]>::try_from(words) {
                Ok(words) => Ok(Key::Predictor(predictor_of_words(&words))),
                Err(_) => Err("is a predictor of other than 85 words"),
            },
            KeyKind::DeltaMush if words.len() % DELTA_MUSH_TERM_WORDS != 0 => {
                Err("is a delta-mush key whose words are not whole terms of 13")
            }
            KeyKind::DeltaMush => Ok(Key::DeltaMush(DeltaMushKey {
                terms: (words.chunks_exact(DELTA_MUSH_TERM_WORDS))
                    .map(|t| DeltaMushTerm {
                        bone: t[0],
                        omega: std::array::from_fn(|i| f32::from_bits(t[1 + i])),
                    })
                    .collect(),
            })),
        }
    }

    /// The predictor, if the key is one.
    pub fn predictor(&self) -> Option<&KeyPredictor> {
        match self {
            Key::Predictor(k) => Some(k),
            Key::DeltaMush(_) => None,
        }
    }

    /// The delta-mush key, if the key is one.
    pub fn delta_mush(&self) -> Option<&DeltaMushKey> {
        match self {
            Key::DeltaMush(k) => Some(k),
            Key::Predictor(_) => None,
        }
    }
}

/// The words of a predictor's record after its tag.
pub const PREDICTOR_WORDS: usize = 85;
/// The words of one delta-mush term: its bone, then Ω (4x3 row-major) as `f32` bits.
const DELTA_MUSH_TERM_WORDS: usize = 13;
const NO_BONE: u32 = u32::MAX;
const IDENTITY: Mat3Rows = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// Every key's record, as the file's KEYS section and the GPU's `Keys` buffer hold them: P + 1
/// offsets (key ℓ's record is words `offsets[ℓ]..offsets[ℓ + 1]`, `offsets[0] = P + 1`), then
/// the records, each its kind's tag ([`KeyKind`]) then:
/// - a predictor: bone u32, second bone u32 (`0xFFFFFFFF`: none), u f32, u2 f32, W 9 f32, W2
///   9 f32, H 63 f32 (85 words);
/// - a delta-mush key: per term, its bone u32, then Ω 12 f32 (13 words a term).
pub fn key_words(keys: &[Key]) -> Vec<u32> {
    let mut words = vec![0u32; keys.len() + 1];
    words[0] = words.len() as u32;
    for (l, key) in keys.iter().enumerate() {
        words.extend(key.record());
        words[l + 1] = words.len() as u32;
    }
    words
}

/// The P keys of [`key_words`]' `words`, or what is wrong with them: structure only (the
/// offsets, each record's tag and length); `validate` checks the content.
pub fn keys_of_words(words: &[u32], p: usize) -> Result<Vec<Key>, ModelProblem> {
    let bad = |key: usize, reason: &'static str| ModelProblem::BadKey { key, reason };
    let offsets = words.get(..p + 1).ok_or(ModelProblem::SectionLength {
        tag: "KEYS".into(),
        expected: 4 * (p as u64 + 1),
        actual: 4 * words.len() as u64,
    })?;
    if offsets[0] as usize != p + 1 || offsets[p] as usize != words.len() {
        return Err(ModelProblem::Dimension {
            what: "the KEYS section's offsets",
            value: u64::from(offsets[0]),
            reason: "must start at P + 1 and end at the section's last word",
        });
    }
    (offsets.windows(2).enumerate())
        .map(|(l, w)| match w[0] <= w[1] {
            true => Key::of_record(&words[w[0] as usize..w[1] as usize]).map_err(|r| bad(l, r)),
            false => Err(bad(l, "has offsets that decrease")),
        })
        .collect()
}

/// A predictor as the 85 words of its record after the tag; `glsl/key.glsl` reads this layout.
pub fn predictor_words(k: &KeyPredictor) -> [u32; PREDICTOR_WORDS] {
    let (b2, u2, w2) = match &k.second {
        Some(s) => (s.bone, s.u, s.w),
        None => (NO_BONE, 0.0, IDENTITY),
    };
    let mut words = [0u32; PREDICTOR_WORDS];
    let head = [k.u, u2];
    let floats = head.iter().chain(&k.w).chain(&w2).chain(&k.h);
    words[0] = k.bone;
    words[1] = b2;
    words[2..]
        .iter_mut()
        .zip(floats)
        .for_each(|(w, f)| *w = f.to_bits());
    words
}

/// A predictor from the 85 words of its record ([`predictor_words`] in reverse).
pub fn predictor_of_words(words: &[u32; PREDICTOR_WORDS]) -> KeyPredictor {
    let f = |i: usize| f32::from_bits(words[i]);
    let rows = |first: usize| std::array::from_fn(|i| f(first + i));
    KeyPredictor {
        bone: words[0],
        u: f(2),
        w: rows(4),
        second: (words[1] != NO_BONE).then(|| SecondBone {
            bone: words[1],
            u: f(3),
            w: rows(13),
        }),
        h: std::array::from_fn(|i| f(22 + i)),
    }
}

/// Turns a 4P x 3P C1 (row-major) for the delta-mush keys of `keys` whose fits give `D P`
/// (`frames[ℓ]`, row-major, for each such key ℓ; None for the others): each such key's three
/// columns times its frame, so that every proxy still reads `D = (D P) Pᵀ`.
pub fn c1_in_key_frames(c1: &mut [f32], frames: &[Option<[[f64; 3]; 3]>]) {
    let p = frames.len();
    for row in c1.chunks_exact_mut(3 * p) {
        for (l, frame) in frames.iter().enumerate() {
            let Some(frame) = frame else { continue };
            let at = 3 * l;
            let old = [0, 1, 2].map(|c| f64::from(row[at + c]));
            for m in 0..3 {
                row[at + m] = (0..3).map(|c| old[c] * frame[c][m]).sum::<f64>() as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys() -> Vec<Key> {
        let predictor = KeyPredictor {
            bone: 1,
            u: 0.5,
            w: IDENTITY,
            second: Some(SecondBone {
                bone: 0,
                u: 0.25,
                w: IDENTITY,
            }),
            h: std::array::from_fn(|i| i as f32),
        };
        let delta_mush = DeltaMushKey {
            terms: vec![
                DeltaMushTerm {
                    bone: 0,
                    omega: std::array::from_fn(|i| i as f32 * 0.5),
                },
                DeltaMushTerm {
                    bone: 2,
                    omega: [1.0; 12],
                },
            ],
        };
        vec![
            Key::DeltaMush(delta_mush),
            Key::Predictor(predictor.clone()),
            {
                Key::Predictor(KeyPredictor {
                    second: None,
                    ..predictor
                })
            },
        ]
    }

    #[test]
    fn the_words_give_back_the_keys_in_any_order_of_kinds() {
        let keys = keys();
        let words = key_words(&keys);
        assert_eq!(words[0], 4);
        assert_eq!(words.len(), 4 + 1 + 26 + 2 * (1 + PREDICTOR_WORDS));
        assert_eq!(keys_of_words(&words, 3).expect("whole"), keys);
        assert_eq!(keys_of_words(&key_words(&[]), 0).expect("none"), []);
    }

    #[test]
    fn a_broken_record_is_named() {
        let words = key_words(&keys());
        let problem = |words: &[u32]| keys_of_words(words, 3).expect_err("broken").to_string();
        let mut unknown = words.clone();
        unknown[words[1] as usize] = 9;
        assert!(problem(&unknown).contains("key 1 has a kind this build does not know"));
        let mut short = words.clone();
        short[1] -= 1; // key 0 loses a word, key 1 gains one
        assert!(problem(&short).contains("key 0 is a delta-mush key whose words"));
        let mut backwards = words.clone();
        backwards[2] = backwards[1] - 1;
        assert!(problem(&backwards).contains("key 1 has offsets that decrease"));
        assert!(problem(&words[..words.len() - 1]).contains("KEYS section's offsets"));
        assert!(problem(&words[..2]).contains("KEYS"));
    }
}
