//! The `.rrs` model file: little-endian, self-describing, checksummed.
//!
//! ```text
//! offset  size       field
//! 0       8          magic  89 'R' 'R' 'S' 0D 0A 1A 0A   (PNG-style: catches text-mode mangling)
//! 8       4          format version (u32) = FORMAT_VERSION (8; versions 1, without CORR,
//!                    PCOR and MUSH, 2, without PCOR and MUSH, 3, without MUSH, 4,
//!                    without PCOR's gravity, 5, without PCOR's ranges, 6, with MUSH's
//!                    terms out of the keys' frames, and 7, with PRED and MUSH for KEYS,
//!                    read too)
//! 12      4          section count S (u32)
//! 16      8          total file length in bytes (u64): truncation is reported as such
//! 24      24 S       section table: tag [u8; 4], reserved u32 (0), offset u64, length u64
//! ...                section payloads (8-byte aligned)
//! end-4   4          CRC-32 (IEEE) of every byte before it
//! ```
//!
//! Sections (unknown tags are skipped, so later versions may add optional ones):
//!
//! | tag  | payload                                              |
//! |------|------------------------------------------------------|
//! | DIMS | V, T, J, P, K as u32                                 |
//! | REST | V x 3 f32                                            |
//! | TRIS | T x 3 u32                                            |
//! | PRNT | J i32 (-1: root)                                     |
//! | SKIX | V x K u32 palette indices                            |
//! | SKIW | V x K f32 weights                                    |
//! | KEYS | version 8: the P keys' words, `key::key_words`: P + 1 u32 offsets, then per key its kind u32 and its record (a predictor: bone u32, second bone u32 (0xFFFFFFFF: none), u f32, u2 f32, W 9 f32, W2 9 f32, H 63 f32; a delta-mush key: per term, bone u32 and Ω 12 f32, in the key's principal frame) |
//! | PRED | before version 8: the predictors, the first P − S keys, 85 words each as in KEYS |
//! | C1   | 4P x 3P f32 (row-major)                              |
//! | C2   | 4P x 4J f32 (row-major)                              |
//! | NGRP | optional: V u32 normal groups (absent: no groups)    |
//! | SSDI | optional: V x K u32 SSD baseline bone indices        |
//! | SSDW | optional: V x K f32 SSD baseline weights             |
//! | ANIM | optional: frames x J x 12 f32 bone transforms        |
//! | TANG | optional: V x 4 f32 rest tangents (xyz, handedness w) |
//! | CORR | optional (version 2): pose-space correctives: N u32, D u32, drivers D u32, map N x 9D f32 (row-major), targets N x V x 3 f32 (target-major) |
//! | PCOR | optional (version 3): proxy correctives: E u32, C u32, features u32 (bit 0 linear; bit 1 gravity, version 5; bit 2 ranges, version 6), D u32 (all drivers), proxies E u32, driver offsets E + 1 u32, drivers D u32, centres C x J x 9 f32, widths J f32 (none when C = 0), up 3 f32 (with gravity only), ranges J x (12 lower, 12 upper) f32 (with ranges only), maps 12 D (9 linear + 3 gravity + C) f32 |
//! | MUSH | optional, versions 4 to 7: delta-mush keys, the last S of the P keys: S u32, N u32 (all their bones), offsets S + 1 u32, bones N u32, terms N x 12 f32 (version 7 in each key's principal frame, C1 turned to match; earlier files are turned as they load, `ModelParts::in_key_frames`) |
//!
//! Decoding checks structure only (bounds, lengths, checksum); the content invariants are
//! checked by `validate` for files and in-memory parts alike.

use super::key::{key_words, keys_of_words, predictor_of_words, PREDICTOR_WORDS};
use super::ProxyCorrectives;
use super::{Correctives, DeltaMushKey, DeltaMushTerm, FeatureRange, Key, ModelParts};
use crate::error::ModelProblem;

pub const MAGIC: [u8; 8] = [0x89, b'R', b'R', b'S', 0x0D, 0x0A, 0x1A, 0x0A];
/// The version this build writes; it reads every version from 1 to this one.
pub const FORMAT_VERSION: u32 = 8;
/// The first version whose delta-mush keys are in their principal frames.
pub const KEY_FRAMES_VERSION: u32 = 7;

const HEADER_BYTES: usize = 24;
const TABLE_ENTRY_BYTES: usize = 24;
const CHECKSUM_BYTES: usize = 4;
/// The first version with one KEYS section for PRED and MUSH.
const KEYS_VERSION: u32 = 8;

const DIMS: [u8; 4] = *b"DIMS";
const REST: [u8; 4] = *b"REST";
const TRIS: [u8; 4] = *b"TRIS";
const PRNT: [u8; 4] = *b"PRNT";
const SKIX: [u8; 4] = *b"SKIX";
const SKIW: [u8; 4] = *b"SKIW";
const KEYS: [u8; 4] = *b"KEYS";
const PRED: [u8; 4] = *b"PRED";
const C1: [u8; 4] = *b"C1\0\0";
const C2: [u8; 4] = *b"C2\0\0";
const NGRP: [u8; 4] = *b"NGRP";
const SSDI: [u8; 4] = *b"SSDI";
const SSDW: [u8; 4] = *b"SSDW";
const ANIM: [u8; 4] = *b"ANIM";
const TANG: [u8; 4] = *b"TANG";
const CORR: [u8; 4] = *b"CORR";
const PCOR: [u8; 4] = *b"PCOR";
const MUSH: [u8; 4] = *b"MUSH";

pub fn encode(m: &ModelParts) -> Vec<u8> {
    let sections = sections(m);
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    push_u32s(&mut out, &[FORMAT_VERSION, sections.len() as u32]);
    out.extend_from_slice(&[0; 8]); // total length, patched below
    let mut offset = align8(HEADER_BYTES + TABLE_ENTRY_BYTES * sections.len());
    for (tag, payload) in &sections {
        out.extend_from_slice(tag);
        push_u32s(&mut out, &[0]);
        out.extend_from_slice(&(offset as u64).to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        offset = align8(offset + payload.len());
    }
    for (_, payload) in &sections {
        out.resize(align8(out.len()), 0);
        out.extend_from_slice(payload);
    }
    let total = (out.len() + CHECKSUM_BYTES) as u64;
    out[16..24].copy_from_slice(&total.to_le_bytes());
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// The model's sections in file order, tag and payload: the required ones, then the optional
/// ones it has.
fn sections(m: &ModelParts) -> Vec<([u8; 4], Vec<u8>)> {
    let (v, t, j, p) = (
        m.rest_positions.len(),
        m.triangles.len(),
        m.bone_parents.len(),
        m.key_count(),
    );
    let mut parents = Vec::new();
    m.bone_parents
        .iter()
        .for_each(|x| parents.extend_from_slice(&x.to_le_bytes()));
    let dims = [v as u32, t as u32, j as u32, p as u32, m.influences];
    let mut sections = vec![
        (DIMS, u32_bytes(&dims)),
        (REST, f32_bytes(m.rest_positions.as_flattened())),
        (TRIS, u32_bytes(m.triangles.as_flattened())),
        (PRNT, parents),
        (SKIX, u32_bytes(&m.skin_indices)),
        (SKIW, f32_bytes(&m.skin_weights)),
        (KEYS, u32_bytes(&key_words(&m.keys))),
        (C1, f32_bytes(&m.c1)),
        (C2, f32_bytes(&m.c2)),
    ];
    if !m.normal_groups.is_empty() {
        sections.push((NGRP, u32_bytes(&m.normal_groups)));
    }
    if !m.baseline_indices.is_empty() {
        sections.push((SSDI, u32_bytes(&m.baseline_indices)));
        sections.push((SSDW, f32_bytes(&m.baseline_weights)));
    }
    if !m.animation.is_empty() {
        sections.push((ANIM, f32_bytes(m.animation.as_flattened())));
    }
    if !m.rest_tangents.is_empty() {
        sections.push((TANG, f32_bytes(m.rest_tangents.as_flattened())));
    }
    if let Some(c) = &m.correctives {
        sections.push((CORR, correctives_bytes(c, v)));
    }
    if let Some(c) = &m.proxy_correctives {
        sections.push((PCOR, proxy_correctives_bytes(c, j)));
    }
    sections
}

/// The CORR payload: N, D, the drivers, the map, the targets.
fn correctives_bytes(c: &Correctives, v: usize) -> Vec<u8> {
    let mut corr = Vec::new();
    let n = c.targets.len() / v.max(1);
    push_u32s(&mut corr, &[n as u32, c.drivers.len() as u32]);
    push_u32s(&mut corr, &c.drivers);
    push_f32s(&mut corr, &c.map);
    push_f32s(&mut corr, c.targets.as_flattened());
    corr
}

/// The PCOR payload: E, C, the feature flags, D, then the proxies, driver offsets, drivers,
/// centres, widths, up, ranges and maps.
fn proxy_correctives_bytes(c: &ProxyCorrectives, j: usize) -> Vec<u8> {
    let mut pcor = Vec::new();
    let kernels = c.kernel_count(j);
    push_u32s(
        &mut pcor,
        &[
            c.proxies.len() as u32,
            kernels as u32,
            u32::from(c.linear)
                | u32::from(c.up.is_some()) << 1
                | u32::from(!c.ranges.is_empty()) << 2,
            c.drivers.len() as u32,
        ],
    );
    push_u32s(&mut pcor, &c.proxies);
    push_u32s(&mut pcor, &c.driver_offsets);
    push_u32s(&mut pcor, &c.drivers);
    push_f32s(&mut pcor, c.centres.as_flattened());
    push_f32s(&mut pcor, &c.widths);
    push_f32s(&mut pcor, c.up.as_slice().as_flattened());
    for r in &c.ranges {
        push_f32s(&mut pcor, &r.lower);
        push_f32s(&mut pcor, &r.upper);
    }
    push_f32s(&mut pcor, &c.maps);
    pcor
}

pub fn decode(bytes: &[u8]) -> Result<(ModelParts, u32), ModelProblem> {
    let body = checked_body(bytes)?;
    let version = le_u32(bytes, 8);
    let table = SectionTable::read(body)?;

    let dims = table.section(body, DIMS, 20)?;
    let [v, t, j, p, k] = [0, 1, 2, 3, 4].map(|i| le_u32(dims, 4 * i) as u64);
    // Expected byte lengths; products saturate, so absurd dimensions fail the length check.
    let words = |factors: &[u64]| factors.iter().fold(4u64, |acc, &f| acc.saturating_mul(f));
    let rest = table.section(body, REST, words(&[v, 3]))?;
    let tris = table.section(body, TRIS, words(&[t, 3]))?;
    let prnt = table.section(body, PRNT, words(&[j]))?;
    let skix = table.section(body, SKIX, words(&[v, k]))?;
    let skiw = table.section(body, SKIW, words(&[v, k]))?;
    let keys = keys(&table, body, version, p)?;
    let c1 = table.section(body, C1, words(&[4, p, 3, p]))?;
    let c2 = table.section(body, C2, words(&[4, p, 4, j]))?;
    let normal_groups = match table.has(NGRP) {
        true => u32s(table.section(body, NGRP, words(&[v]))?),
        false => Vec::new(),
    };
    let (baseline_indices, baseline_weights) = match table.has(SSDI) || table.has(SSDW) {
        true => (
            u32s(table.section(body, SSDI, words(&[v, k]))?),
            f32s(table.section(body, SSDW, words(&[v, k]))?),
        ),
        false => (Vec::new(), Vec::new()),
    };
    let animation = animation(&table, body)?;

    let rest_tangents = match table.has(TANG) {
        true => f32s(table.section(body, TANG, words(&[v, 4]))?)
            .chunks_exact(4)
            .map(array)
            .collect(),
        false => Vec::new(),
    };

    let correctives = match table.entry(CORR) {
        Some(length) => Some(correctives(&table, body, length, v)?),
        None => None,
    };

    let proxy_correctives = match table.entry(PCOR) {
        Some(length) => Some(proxy_correctives(&table, body, length, j)?),
        None => None,
    };

    let parts = ModelParts {
        rest_positions: f32s(rest).chunks_exact(3).map(array).collect(),
        triangles: u32s(tris).chunks_exact(3).map(array).collect(),
        bone_parents: prnt
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes(array(b)))
            .collect(),
        influences: k as u32,
        skin_indices: u32s(skix),
        skin_weights: f32s(skiw),
        keys,
        c1: f32s(c1),
        c2: f32s(c2),
        normal_groups,
        baseline_indices,
        baseline_weights,
        animation,
        rest_tangents,
        correctives,
        proxy_correctives,
    };
    Ok((parts, version))
}

/// The P keys: the KEYS section, or before version 8 the PRED section's predictors then the
/// MUSH section's delta-mush keys.
fn keys(table: &SectionTable, body: &[u8], version: u32, p: u64) -> Result<Vec<Key>, ModelProblem> {
    if version < KEYS_VERSION {
        return legacy_keys(table, body, p);
    }
    let length = (table.entry(KEYS)).ok_or(ModelProblem::MissingSection { tag: "KEYS".into() })?;
    if length % 4 != 0 {
        return Err(ModelProblem::SectionLength {
            tag: "KEYS".into(),
            expected: length / 4 * 4,
            actual: length,
        });
    }
    keys_of_words(&u32s(table.section(body, KEYS, length)?), p as usize)
}

/// The keys of a file before version 8: the PRED predictors, then the MUSH delta-mush keys.
fn legacy_keys(table: &SectionTable, body: &[u8], p: u64) -> Result<Vec<Key>, ModelProblem> {
    let delta_mush = match table.entry(MUSH) {
        Some(length) => delta_mush_keys(table, body, length)?,
        None => Vec::new(),
    };
    let delta_mush_count = delta_mush.len() as u64;
    if delta_mush_count > p {
        return Err(ModelProblem::Dimension {
            what: "the MUSH section's key count",
            value: delta_mush_count,
            reason: "must not exceed DIMS's P",
        });
    }
    let expected = (p - delta_mush_count).saturating_mul(4 * PREDICTOR_WORDS as u64);
    let pred = u32s(table.section(body, PRED, expected)?);
    let predictors = (pred.chunks_exact(PREDICTOR_WORDS))
        .map(|record| Key::Predictor(predictor_of_words(&array(record))));
    Ok(predictors
        .chain(delta_mush.into_iter().map(Key::DeltaMush))
        .collect())
}

/// The MUSH section (versions 4 to 7): S and N, then the lengths they give (checked before
/// anything else is read), then the keys of its CSR offsets.
fn delta_mush_keys(
    table: &SectionTable,
    body: &[u8],
    length: u64,
) -> Result<Vec<DeltaMushKey>, ModelProblem> {
    const HEAD: u64 = 8;
    if length < HEAD {
        return Err(ModelProblem::SectionLength {
            tag: "MUSH".into(),
            expected: HEAD,
            actual: length,
        });
    }
    let head = table.section(body, MUSH, length)?;
    let [s, n] = [0, 1].map(|i| le_u32(head, 4 * i) as u64);
    let words = [2, s + 1, n, n.saturating_mul(12)]
        .into_iter()
        .fold(0u64, u64::saturating_add);
    let delta_mush = u32s(table.section(body, MUSH, words.saturating_mul(4))?);
    let (s, n) = (s as usize, n as usize);
    let (offsets, rest) = delta_mush[2..].split_at(s + 1);
    let (bones, terms) = rest.split_at(n);
    let in_order = offsets.first() == Some(&0) && offsets.last() == Some(&(n as u32));
    if !in_order || offsets.windows(2).any(|w| w[1] < w[0]) {
        return Err(ModelProblem::Dimension {
            what: "the MUSH section's offsets",
            value: u64::from(offsets[0]),
            reason: "must run from 0 to the bone count without decreasing",
        });
    }
    let term = |i: usize| DeltaMushTerm {
        bone: bones[i],
        omega: std::array::from_fn(|k| f32::from_bits(terms[12 * i + k])),
    };
    Ok((offsets.windows(2))
        .map(|w| DeltaMushKey {
            terms: (w[0] as usize..w[1] as usize).map(term).collect(),
        })
        .collect())
}

/// The file less its checksum, once the magic, the version, the length field and the checksum
/// hold.
fn checked_body(bytes: &[u8]) -> Result<&[u8], ModelProblem> {
    need(bytes.len(), 0, HEADER_BYTES, "the header")?;
    if bytes[..8] != MAGIC {
        return Err(ModelProblem::BadMagic);
    }
    let version = le_u32(bytes, 8);
    if !(1..=FORMAT_VERSION).contains(&version) {
        return Err(ModelProblem::UnsupportedVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let declared = le_u64(bytes, 16);
    if declared != bytes.len() as u64 {
        return Err(length_problem(bytes, declared));
    }
    need(bytes.len(), HEADER_BYTES, CHECKSUM_BYTES, "the checksum")?;
    let body = &bytes[..bytes.len() - CHECKSUM_BYTES];
    let stored = le_u32(bytes, body.len());
    let computed = crc32fast::hash(body);
    if stored != computed {
        return Err(ModelProblem::Checksum { stored, computed });
    }
    Ok(body)
}

/// What a file whose length is not the `declared` one has.
fn length_problem(bytes: &[u8], declared: u64) -> ModelProblem {
    // A cut (or extended) file and a damaged length field look alike; the checksum,
    // recomputed with the real length, tells them apart when only the field is damaged.
    if only_the_length_is_damaged(bytes) {
        return ModelProblem::Dimension {
            what: "the file length in the header",
            value: declared,
            reason: "corrupted (the checksum holds for the file's real length)",
        };
    }
    if declared > bytes.len() as u64 {
        return ModelProblem::Truncated {
            what: "the file (or its header's length field is corrupted)".into(),
            expected: declared,
            actual: bytes.len() as u64,
        };
    }
    ModelProblem::TrailingBytes {
        declared,
        actual: bytes.len() as u64,
    }
}

/// The optional ANIM section: any length that is whole transforms (`validate` checks it
/// against J).
fn animation(table: &SectionTable, body: &[u8]) -> Result<Vec<[f32; 12]>, ModelProblem> {
    match table.entry(ANIM) {
        Some(length) if length % 48 == 0 => Ok(f32s(table.section(body, ANIM, length)?)
            .chunks_exact(12)
            .map(array)
            .collect()),
        Some(length) => Err(ModelProblem::SectionLength {
            tag: "ANIM".into(),
            expected: length / 48 * 48,
            actual: length,
        }),
        None => Ok(Vec::new()),
    }
}

/// The PCOR section: E, C, the feature flags and D, then the lengths they give (checked before
/// anything else is read).
fn proxy_correctives(
    table: &SectionTable,
    body: &[u8],
    length: u64,
    j: u64,
) -> Result<ProxyCorrectives, ModelProblem> {
    const HEAD: u64 = 16;
    if length < HEAD {
        return Err(ModelProblem::SectionLength {
            tag: "PCOR".into(),
            expected: HEAD,
            actual: length,
        });
    }
    let head = table.section(body, PCOR, length)?;
    let [e, c, flags, d] = [0, 1, 2, 3].map(|i| le_u32(head, 4 * i) as u64);
    if flags > 7 {
        return Err(ModelProblem::Dimension {
            what: "the PCOR section's feature flags",
            value: flags,
            reason: "must be 0 to 7 (bit 0 linear, bit 1 gravity, bit 2 ranges)",
        });
    }
    let (linear, gravity, ranges) = (flags & 1, flags >> 1 & 1, flags >> 2);
    let product = |factors: &[u64]| factors.iter().fold(1u64, |acc, &f| acc.saturating_mul(f));
    let widths = if c > 0 { j } else { 0 };
    let centres = product(&[c, j, 9]);
    let maps = product(&[12, d, 9 * linear + 3 * gravity + c]);
    let words = [
        4,
        e,
        e.saturating_add(1),
        d,
        centres,
        widths,
        3 * gravity,
        product(&[ranges, j, 24]),
        maps,
    ]
    .into_iter()
    .fold(0u64, u64::saturating_add);
    let pcor = table.section(body, PCOR, words.saturating_mul(4))?;
    let (e, d, centres, widths) = (e as usize, d as usize, centres as usize, widths as usize);
    let mut at = 16;
    let mut take = |count: usize| {
        let slice = &pcor[at..at + 4 * count];
        at += 4 * count;
        slice
    };
    let proxies = u32s(take(e));
    let driver_offsets = u32s(take(e + 1));
    let drivers = u32s(take(d));
    let centres = f32s(take(centres)).chunks_exact(9).map(array).collect();
    let widths = f32s(take(widths));
    let up = (gravity == 1).then(|| array(&f32s(take(3))));
    let ranges = f32s(take(24 * ranges as usize * j as usize))
        .chunks_exact(24)
        .map(|r| FeatureRange {
            lower: array(&r[..12]),
            upper: array(&r[12..]),
        })
        .collect();
    let maps = f32s(take(maps as usize));
    Ok(ProxyCorrectives {
        linear: linear == 1,
        up,
        centres,
        widths,
        ranges,
        proxies,
        driver_offsets,
        drivers,
        maps,
    })
}

/// The CORR section: N and D, then the lengths they give (checked before anything is read).
fn correctives(
    table: &SectionTable,
    body: &[u8],
    length: u64,
    v: u64,
) -> Result<Correctives, ModelProblem> {
    if length < 8 {
        return Err(ModelProblem::SectionLength {
            tag: "CORR".into(),
            expected: 8,
            actual: length,
        });
    }
    let head = table.section(body, CORR, length)?;
    let (n, d) = (le_u32(head, 0) as u64, le_u32(head, 4) as u64);
    let floats = |factors: &[u64]| factors.iter().fold(1u64, |acc, &f| acc.saturating_mul(f));
    let (map, targets) = (floats(&[n, 9, d]), floats(&[n, v, 3]));
    let words = 2u64
        .saturating_add(d)
        .saturating_add(map)
        .saturating_add(targets);
    let corr = table.section(body, CORR, words.saturating_mul(4))?;
    let (d, map) = (d as usize, map as usize);
    let values = f32s(&corr[8 + 4 * d..]);
    Ok(Correctives {
        drivers: u32s(&corr[8..8 + 4 * d]),
        map: values[..map].to_vec(),
        targets: values[map..].chunks_exact(3).map(array).collect(),
    })
}

struct SectionTable {
    entries: Vec<([u8; 4], u64, u64)>,
}

impl SectionTable {
    fn read(body: &[u8]) -> Result<Self, ModelProblem> {
        let count = le_u32(body, 12) as usize;
        need(
            body.len(),
            HEADER_BYTES,
            count.saturating_mul(TABLE_ENTRY_BYTES),
            "the section table",
        )?;
        let mut entries: Vec<([u8; 4], u64, u64)> = Vec::with_capacity(count);
        for i in 0..count {
            let e = HEADER_BYTES + i * TABLE_ENTRY_BYTES;
            let tag: [u8; 4] = array(&body[e..e + 4]);
            let offset = le_u64(body, e + 8);
            let length = le_u64(body, e + 16);
            if entries.iter().any(|(t, _, _)| *t == tag) {
                return Err(ModelProblem::DuplicateSection { tag: tag_name(tag) });
            }
            let end = offset.checked_add(length);
            if offset < (HEADER_BYTES + count * TABLE_ENTRY_BYTES) as u64
                || end.is_none_or(|end| end > body.len() as u64)
            {
                return Err(ModelProblem::SectionBounds {
                    tag: tag_name(tag),
                    offset,
                    length,
                    file_length: (body.len() + CHECKSUM_BYTES) as u64,
                });
            }
            entries.push((tag, offset, length));
        }
        Ok(SectionTable { entries })
    }

    fn has(&self, tag: [u8; 4]) -> bool {
        self.entry(tag).is_some()
    }

    /// The length of a section, if present.
    fn entry(&self, tag: [u8; 4]) -> Option<u64> {
        self.entries
            .iter()
            .find(|(t, _, _)| *t == tag)
            .map(|&(_, _, length)| length)
    }

    /// The payload of a required section, checked against its expected length.
    fn section<'a>(
        &self,
        body: &'a [u8],
        tag: [u8; 4],
        expected: u64,
    ) -> Result<&'a [u8], ModelProblem> {
        let &(_, offset, length) = self
            .entries
            .iter()
            .find(|(t, _, _)| *t == tag)
            .ok_or_else(|| ModelProblem::MissingSection { tag: tag_name(tag) })?;
        if expected != length {
            return Err(ModelProblem::SectionLength {
                tag: tag_name(tag),
                expected,
                actual: length,
            });
        }
        Ok(&body[offset as usize..(offset + length) as usize])
    }
}

/// Whether the file checks out once its length field (bytes 16..24) says its real length.
fn only_the_length_is_damaged(bytes: &[u8]) -> bool {
    if bytes.len() < HEADER_BYTES + CHECKSUM_BYTES {
        return false;
    }
    let mut fixed = bytes.to_vec();
    fixed[16..24].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
    let body = fixed.len() - CHECKSUM_BYTES;
    le_u32(&fixed, body) == crc32fast::hash(&fixed[..body])
}

fn need(len: usize, at: usize, count: usize, what: &str) -> Result<(), ModelProblem> {
    let left = len.saturating_sub(at);
    if left < count {
        return Err(ModelProblem::Truncated {
            what: what.to_string(),
            expected: count as u64,
            actual: left as u64,
        });
    }
    Ok(())
}

fn tag_name(tag: [u8; 4]) -> String {
    tag.iter()
        .take_while(|&&b| b != 0)
        .map(|&b| if b.is_ascii_graphic() { b as char } else { '?' })
        .collect()
}

fn align8(x: usize) -> usize {
    x.div_ceil(8) * 8
}

fn array<T: Copy + Default, const N: usize>(s: &[T]) -> [T; N] {
    let mut a = [T::default(); N];
    a.copy_from_slice(s);
    a
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(array(&b[at..at + 4]))
}

fn le_u64(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(array(&b[at..at + 8]))
}

fn u32s(b: &[u8]) -> Vec<u32> {
    b.chunks_exact(4)
        .map(|w| u32::from_le_bytes(array(w)))
        .collect()
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|w| f32::from_le_bytes(array(w)))
        .collect()
}

fn u32_bytes(xs: &[u32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 * xs.len());
    push_u32s(&mut out, xs);
    out
}

fn f32_bytes(xs: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 * xs.len());
    push_f32s(&mut out, xs);
    out
}

fn push_u32s(out: &mut Vec<u8>, xs: &[u32]) {
    xs.iter()
        .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
}

fn push_f32s(out: &mut Vec<u8>, xs: &[f32]) {
    xs.iter()
        .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
}
