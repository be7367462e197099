//! The `.rrs` loader: exact round trips, and every kind of bad file rejected with the error that
//! names the problem (never a panic, never a silently wrong model).

mod common;

use proptest::prelude::*;
use rrskin::model::{FORMAT_VERSION, MAGIC};
use rrskin::{DeltaMushKey, DeltaMushTerm, Error, Key, KeyKind, Model, ModelProblem};
use rrskin_render::synthetic::{random_model, Spec};

fn model(proxies: usize, influences: u32) -> Model {
    random_model(
        Spec {
            grid: 5,
            bones: 4,
            proxies,
            influences,
        },
        42,
    )
    .expect("valid")
}

fn problem(result: rrskin::Result<Model>) -> ModelProblem {
    match result {
        Err(Error::BadModel { problem, .. }) => problem,
        other => panic!("expected a BadModel error, got {other:?}"),
    }
}

/// Byte offset of a section's payload, read from the documented section table.
fn section(bytes: &[u8], tag: &[u8; 4]) -> usize {
    let count = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    (0..count)
        .map(|i| 24 + 24 * i)
        .find(|&e| &bytes[e..e + 4] == tag)
        .map(|e| u64::from_le_bytes(bytes[e + 8..e + 16].try_into().expect("8 bytes")) as usize)
        .expect("section present")
}

/// Recomputes the trailing CRC so that a deliberate edit passes the corruption check.
fn reseal(bytes: &mut [u8]) {
    let n = bytes.len() - 4;
    let crc = crc32fast::hash(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}

fn put_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

fn le_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"))
}

/// Byte offset of word `w` of key `l`'s record in the KEYS section, after its kind's tag.
fn key_word(bytes: &[u8], l: usize, w: usize) -> usize {
    let keys = section(bytes, b"KEYS");
    keys + 4 * (le_u32(bytes, keys + 4 * l) as usize + 1 + w)
}

/// Every section of a file, tag and payload, in table order.
fn sections(bytes: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
    let count = le_u32(bytes, 12) as usize;
    (0..count)
        .map(|i| {
            let e = 24 + 24 * i;
            let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8"));
            let (offset, length) = (word(e + 8) as usize, word(e + 16) as usize);
            (
                bytes[e..e + 4].try_into().expect("4"),
                bytes[offset..offset + length].to_vec(),
            )
        })
        .collect()
}

/// A file of `version` holding `sections`, laid out as the format documents.
fn file_of(version: u32, sections: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
    let align8 = |n: usize| n.div_ceil(8) * 8;
    let mut out = MAGIC.to_vec();
    out.extend(version.to_le_bytes());
    out.extend((sections.len() as u32).to_le_bytes());
    out.extend([0; 8]);
    let mut offset = align8(24 + 24 * sections.len());
    for (tag, payload) in sections {
        out.extend(tag);
        out.extend([0; 4]);
        out.extend((offset as u64).to_le_bytes());
        out.extend((payload.len() as u64).to_le_bytes());
        offset = align8(offset + payload.len());
    }
    for (_, payload) in sections {
        out.resize(align8(out.len()), 0);
        out.extend(payload);
    }
    let total = (out.len() + 4) as u64;
    out[16..24].copy_from_slice(&total.to_le_bytes());
    out.extend([0; 4]);
    reseal(&mut out);
    out
}

/// `m` as a file of `version` (before 8) held it: its keys (predictors first) as PRED, the
/// predictors' records, and MUSH, the delta-mush keys' CSR, where it has some.
fn legacy_file(m: &Model, version: u32) -> Vec<u8> {
    let words = |ws: &[u32]| ws.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>();
    let (mut pred, mut offsets, mut bones, mut terms) = (vec![], vec![0], vec![], vec![]);
    for key in m.keys() {
        match key {
            rrskin::Key::Predictor(k) => {
                assert!(offsets.len() == 1, "predictors come first in a legacy file");
                pred.extend(rrskin::model::predictor_words(k));
            }
            rrskin::Key::DeltaMush(k) => {
                bones.extend(k.terms.iter().map(|t| t.bone));
                terms.extend(k.terms.iter().flat_map(|t| t.omega.map(f32::to_bits)));
                offsets.push(bones.len() as u32);
            }
        }
    }
    let mut out = Vec::new();
    for (tag, payload) in sections(&m.to_bytes()) {
        match &tag {
            b"KEYS" => out.push((*b"PRED", words(&pred))),
            _ => out.push((tag, payload)),
        }
    }
    if offsets.len() > 1 {
        let head = [offsets.len() as u32 - 1, bones.len() as u32];
        let all: Vec<u32> = [&head[..], &offsets, &bones, &terms].concat();
        out.push((*b"MUSH", words(&all)));
    }
    file_of(version, &out)
}

#[test]
fn valid_models_round_trip_exactly() {
    for (p, k) in [(0, 4), (0, 8), (3, 4), (6, 8)] {
        let m = model(p, k);
        let bytes = m.to_bytes();
        assert_eq!(&bytes[..8], &MAGIC);
        let back = Model::from_bytes(&bytes).expect("round trip");
        assert_eq!(back, m);
        assert_eq!(back.to_bytes(), bytes, "encoding is deterministic");
    }
    let dir = common::scratch::temp_dir("roundtrip");
    let path = dir.join("m.rrs");
    let m = model(2, 4);
    m.save(&path).expect("save");
    assert_eq!(Model::load(&path).expect("load"), m);
}

#[test]
fn truncated_files_are_reported_as_truncated() {
    let bytes = model(3, 4).to_bytes();
    for cut in [0, 7, 20] {
        assert!(matches!(
            problem(Model::from_bytes(&bytes[..cut])),
            ModelProblem::Truncated { ref what, .. } if what == "the header"
        ));
    }
    for cut in [24, bytes.len() / 2, bytes.len() - 1] {
        assert_eq!(
            problem(Model::from_bytes(&bytes[..cut])),
            ModelProblem::Truncated {
                what: "the file (or its header's length field is corrupted)".into(),
                expected: bytes.len() as u64,
                actual: cut as u64
            }
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(
        problem(Model::from_bytes(&longer)),
        ModelProblem::TrailingBytes { .. }
    ));
}

/// A flipped byte in the header's length field is corruption, not a truncated file of absurd
/// size (issue 13): said so, since the checksum holds for the real length.
#[test]
fn a_damaged_length_field_is_reported_as_corruption() {
    let bytes = model(3, 4).to_bytes();
    for (at, flip) in [(20, 0x01), (16, 0x40), (17, 0x80)] {
        let mut bad = bytes.clone();
        bad[at] ^= flip;
        let text = problem(Model::from_bytes(&bad)).to_string();
        assert!(
            text.contains("length in the header") && text.contains("corrupted"),
            "flip at {at}: {text}"
        );
    }
    // Cut short, a file with a damaged length could be either: both are named.
    let text = problem(Model::from_bytes(&bytes[..bytes.len() - 8])).to_string();
    assert!(
        text.contains("truncated") && text.contains("corrupted"),
        "{text}"
    );
}

#[test]
fn bit_flips_are_caught_by_the_checksum() {
    let bytes = model(3, 8).to_bytes();
    // Every bit after the header's fixed fields (magic, version, length) is covered by the CRC.
    for at in (24..bytes.len()).step_by(7) {
        let mut bad = bytes.clone();
        bad[at] ^= 1 << (at % 8);
        let p = problem(Model::from_bytes(&bad));
        assert!(
            matches!(p, ModelProblem::Checksum { .. }),
            "flip at {at}: {p:?}"
        );
    }
    let mut bad = bytes.clone();
    bad[1] ^= 0x20;
    assert_eq!(problem(Model::from_bytes(&bad)), ModelProblem::BadMagic);
}

#[test]
fn other_versions_are_refused_by_number() {
    let mut bytes = model(1, 4).to_bytes();
    put_u32(&mut bytes, 8, FORMAT_VERSION + 1);
    assert_eq!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::UnsupportedVersion {
            found: FORMAT_VERSION + 1,
            supported: FORMAT_VERSION
        }
    );
}

#[test]
fn nan_and_infinity_are_refused_where_they_are() {
    let good = model(3, 4).to_bytes();
    for (tag, what, index) in [
        (b"REST", "rest positions", 5usize),
        (b"SKIW", "skin weights", 2),
        (b"C1\0\0", "C1", 7),
        (b"C2\0\0", "C2", 0),
    ] {
        let mut bytes = good.clone();
        let at = section(&bytes, tag) + 4 * index;
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        reseal(&mut bytes);
        assert_eq!(
            problem(Model::from_bytes(&bytes)),
            ModelProblem::NonFinite { what, index }
        );
    }
    let mut bytes = good.clone();
    let at = key_word(&bytes, 1, 30); // predictor 1, an element of H
    bytes[at..at + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    reseal(&mut bytes);
    assert_eq!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::NonFinite {
            what: "predictor H",
            index: 1
        }
    );
}

#[test]
fn out_of_range_indices_are_refused_with_the_bound() {
    let m = model(3, 4);
    let (v, j, p) = (m.vertex_count(), m.bone_count(), m.proxy_count());
    let good = m.to_bytes();
    let cases: [(usize, u32, &str, usize); 4] = [
        (section(&good, b"TRIS") + 16, v as u32, "triangles", v),
        (
            section(&good, b"SKIX") + 24,
            (p + j) as u32,
            "skin indices",
            p + j,
        ),
        (section(&good, b"PRNT") + 8, j as u32, "bone parents", j),
        (key_word(&good, 1, 0), j as u32, "predictor bone", j),
    ];
    for (at, value, what, bound) in cases {
        let mut bytes = good.clone();
        put_u32(&mut bytes, at, value);
        reseal(&mut bytes);
        let p = problem(Model::from_bytes(&bytes));
        match p {
            ModelProblem::IndexOutOfRange {
                what: w,
                value: x,
                bound: b,
                ..
            } => {
                assert_eq!((w, x, b), (what, value as i64, bound))
            }
            other => panic!("{what}: {other:?}"),
        }
    }
}

#[test]
fn inconsistent_content_is_refused() {
    let good = model(2, 4).to_bytes();
    // A dimension that disagrees with a section's length.
    let mut bytes = good.clone();
    let at = section(&bytes, b"DIMS");
    put_u32(&mut bytes, at, 1000);
    reseal(&mut bytes);
    assert!(matches!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::SectionLength { ref tag, .. } if tag == "REST"
    ));
    // A W that is not a rotation.
    let mut bytes = good.clone();
    let at = key_word(&bytes, 0, 4);
    bytes[at..at + 4].copy_from_slice(&2.0f32.to_le_bytes());
    reseal(&mut bytes);
    assert!(matches!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::NotRotation {
            what: "predictor W",
            index: 0,
            ..
        }
    ));
    // Weights that do not sum to one.
    let mut bytes = good.clone();
    let at = section(&bytes, b"SKIW");
    bytes[at..at + 4].copy_from_slice(&5.0f32.to_le_bytes());
    reseal(&mut bytes);
    assert!(matches!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::BadWeights { vertex: 0, .. }
    ));
    // A cycle in the bone hierarchy.
    let mut bytes = good.clone();
    let at = section(&bytes, b"PRNT");
    put_u32(&mut bytes, at, 1);
    let at = section(&bytes, b"PRNT") + 4;
    put_u32(&mut bytes, at, 0);
    reseal(&mut bytes);
    assert!(matches!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::ParentCycle { .. }
    ));
    // A missing section.
    let mut bytes = good.clone();
    let e = (0..9)
        .map(|i| 24 + 24 * i)
        .find(|&e| &bytes[e..e + 4] == b"C2\0\0")
        .expect("C2");
    bytes[e..e + 4].copy_from_slice(b"XXXX");
    reseal(&mut bytes);
    assert_eq!(
        problem(Model::from_bytes(&bytes)),
        ModelProblem::MissingSection { tag: "C2".into() }
    );
}

#[test]
fn file_errors_name_the_file() {
    let dir = common::scratch::temp_dir("badfile");
    let path = dir.join("broken.rrs");
    std::fs::write(&path, b"not a model at all, just some text").expect("write");
    let err = Model::load(&path).expect_err("not a model");
    let text = err.to_string();
    assert!(
        text.contains("broken.rrs") && text.contains("bad magic"),
        "{text}"
    );
    let missing = Model::load(dir.join("absent.rrs")).expect_err("absent");
    assert!(matches!(missing, Error::Io { ref path, .. } if path.ends_with("absent.rrs")));
}

/// The problem [`Model::new`] finds in a model of the tests' shape with proxy correctives
/// ([`proxy_corrected`]) after `edit`.
fn edited_proxy_correctives(edit: &dyn Fn(&mut rrskin::ProxyCorrectives)) -> ModelProblem {
    let mut parts = proxy_corrected(true, 2, 4).into_parts();
    edit(parts.proxy_correctives.as_mut().expect("proxy correctives"));
    problem(Model::new(parts))
}

/// The model's up, where the proxy correctives see gravity: of unit length and finite; gravity
/// alone, or with kernels, is a basis.
#[test]
fn a_proxy_corrective_up_is_unit_and_finite() {
    let parts = proxy_corrected(true, 2, 4).into_parts();
    let with = edited_proxy_correctives;
    let gravity_only = |up: [f32; 3]| {
        with(&|c| {
            c.linear = false;
            c.up = Some(up);
            c.centres.clear();
            c.widths.clear();
            c.maps = vec![0.0; 12 * 4 * 3];
        })
    };
    assert!(matches!(
        gravity_only([0.0, 2.0, 0.0]),
        ModelProblem::BadProxyCorrective { what: "up", .. }
    ));
    assert!(matches!(
        gravity_only([0.0, f32::NAN, 1.0]),
        ModelProblem::NonFinite { index: 1, .. }
    ));
    let mut alone = parts.clone();
    let c = alone.proxy_correctives.as_mut().expect("proxy correctives");
    (c.linear, c.up, c.maps) = (false, Some([1.0, 0.0, 0.0]), vec![0.0; 12 * 4 * (3 + 2)]);
    Model::new(alone).expect("gravity and kernels without the linear features");
}

/// Feature ranges: one per joint or none, finite, and containing 0 (the rest pose's features).
#[test]
fn proxy_corrective_ranges_contain_the_rest_pose_and_are_finite() {
    let parts = proxy_corrected(true, 2, 4).into_parts();
    let with = edited_proxy_correctives;
    assert!(matches!(
        with(&|c| c.ranges[2].lower[4] = 0.1),
        ModelProblem::BadProxyCorrective {
            what: "ranges",
            index: 2,
            ..
        }
    ));
    assert!(matches!(
        with(&|c| c.ranges[1].upper[10] = -0.1),
        ModelProblem::BadProxyCorrective {
            what: "ranges",
            index: 1,
            ..
        }
    ));
    assert!(matches!(
        with(&|c| c.ranges[0].upper[3] = f32::INFINITY),
        ModelProblem::NonFinite {
            what: "proxy corrective feature ranges",
            index: 15
        }
    ));
    assert!(matches!(
        with(&|c| {
            c.ranges.pop();
        }),
        ModelProblem::Length {
            expected: 4,
            actual: 3,
            ..
        }
    ));
    let mut zero = parts.clone();
    let c = zero.proxy_correctives.as_mut().expect("proxy correctives");
    c.ranges.iter_mut().for_each(|r| {
        *r = rrskin::FeatureRange {
            lower: [0.0; 12],
            upper: [0.0; 12],
        }
    });
    Model::new(zero).expect("ranges of 0: joints that never moved");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Arbitrary edits (overwrite a run of bytes, then cut anywhere) never panic, and never
    /// yield a model unless the file is unchanged.
    #[test]
    fn corrupted_files_never_panic(at in 0usize..4000, junk in proptest::collection::vec(any::<u8>(), 1..16), cut in 0usize..4000) {
        let good = model(2, 4).to_bytes();
        let mut bytes = good.clone();
        let at = at % bytes.len();
        for (i, b) in junk.iter().enumerate() {
            if at + i < bytes.len() {
                bytes[at + i] = *b;
            }
        }
        bytes.truncate(cut.max(1).min(bytes.len()));
        match Model::from_bytes(&bytes) {
            Ok(m) => prop_assert_eq!(bytes, good, "accepted a changed file: {:?}", m.vertex_count()),
            Err(Error::BadModel { .. }) => {}
            Err(other) => prop_assert!(false, "unexpected error kind {:?}", other),
        }
    }

    /// Random bytes behind a valid header never panic either.
    #[test]
    fn random_bodies_never_panic(body in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut bytes = MAGIC.to_vec();
        bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        bytes.extend_from_slice(&body);
        let _ = Model::from_bytes(&bytes);
        if bytes.len() >= 28 {
            let n = bytes.len() as u64;
            bytes[16..24].copy_from_slice(&n.to_le_bytes());
            reseal(&mut bytes);
            prop_assert!(Model::from_bytes(&bytes).is_err());
        }
    }
}

#[test]
fn normal_groups_round_trip_and_are_checked() {
    let mut parts = model(2, 4).into_parts();
    let v = parts.rest_positions.len();
    parts.normal_groups = (0..v as u32).map(|a| a - a % 2).collect();
    let m = Model::new(parts.clone()).expect("valid groups");
    let back = Model::from_bytes(&m.to_bytes()).expect("round trip");
    assert_eq!(back, m);
    // Vertices 0 and 1 share a group, so they share their incident triangles.
    let (off, list) = back.incidence();
    assert_eq!(
        &list[off[0] as usize..off[1] as usize],
        &list[off[1] as usize..off[2] as usize]
    );
    parts.normal_groups[3] = v as u32;
    assert!(matches!(
        problem(Model::new(parts.clone())),
        ModelProblem::IndexOutOfRange {
            what: "normal groups",
            index: 3,
            ..
        }
    ));
    parts.normal_groups.pop();
    assert!(matches!(
        problem(Model::new(parts)),
        ModelProblem::Length {
            what: "normal groups",
            ..
        }
    ));
}

#[test]
fn an_animation_round_trips_and_is_checked() {
    let mut parts = model(1, 4).into_parts();
    let j = parts.bone_parents.len();
    let identity: rrskin::predict::Affine =
        [1.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    parts.animation = vec![identity; 3 * j];
    let m = Model::new(parts.clone()).expect("valid animation");
    let back = Model::from_bytes(&m.to_bytes()).expect("round trip");
    assert_eq!(back.animation().count(), 3);
    assert_eq!(back, m);
    parts.animation.pop();
    assert!(matches!(
        problem(Model::new(parts.clone())),
        ModelProblem::Length {
            what: "animation (frames x bones)",
            ..
        }
    ));
    parts.animation.push(identity);
    parts.animation[1][0] = 2.0;
    assert!(matches!(
        problem(Model::new(parts)),
        ModelProblem::NotRotation {
            what: "animation rotation",
            index: 1,
            ..
        }
    ));
}

#[test]
fn rest_tangents_round_trip_and_are_checked() {
    let m = model(2, 4);
    assert!(m.has_tangents(), "synthetic models carry tangents");
    let back = Model::from_bytes(&m.to_bytes()).expect("round trip");
    assert_eq!(back, m);
    // A file without the optional section (as written before tangents existed) loads bare.
    let mut parts = m.into_parts();
    let tangents = std::mem::take(&mut parts.rest_tangents);
    let bare = Model::new(parts.clone()).expect("valid without tangents");
    assert!(!Model::from_bytes(&bare.to_bytes())
        .expect("load")
        .has_tangents());
    parts.rest_tangents = tangents[1..].to_vec();
    assert!(matches!(
        problem(Model::new(parts.clone())),
        ModelProblem::Length {
            what: "rest tangents",
            ..
        }
    ));
    for (bad, vertex) in [([2.0, 0.0, 0.0, 1.0], 3), ([1.0, 0.0, 0.0, 0.5], 4)] {
        parts.rest_tangents = tangents.clone();
        parts.rest_tangents[vertex] = bad;
        assert!(matches!(
            problem(Model::new(parts.clone())),
            ModelProblem::BadTangent { vertex: v, .. } if v == vertex
        ));
    }
    parts.rest_tangents = tangents;
    parts.rest_tangents[0][1] = f32::NAN;
    assert!(matches!(
        problem(Model::new(parts)),
        ModelProblem::NonFinite {
            what: "rest tangents",
            ..
        }
    ));
}

/// Byte offset of a section's entry in the section table (its tag), and its payload's length.
fn table_entry(bytes: &[u8], tag: &[u8; 4]) -> (usize, u64) {
    let count = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    let e = (0..count)
        .map(|i| 24 + 24 * i)
        .find(|&e| &bytes[e..e + 4] == tag)
        .expect("section present");
    let length = u64::from_le_bytes(bytes[e + 16..e + 24].try_into().expect("8 bytes"));
    (e, length)
}

/// `m`'s bytes, after checking that they carry this build's version and load back as `m`,
/// which encodes to the same bytes (the encoding is deterministic).
fn round_trip(m: &Model) -> Vec<u8> {
    let bytes = m.to_bytes();
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().expect("4")),
        FORMAT_VERSION
    );
    let back = Model::from_bytes(&bytes).expect("round trip");
    assert_eq!(&back, m);
    assert_eq!(back.to_bytes(), bytes, "encoding is deterministic");
    bytes
}

#[test]
fn correctives_round_trip_and_version_1_files_still_load() {
    for (p, k) in [(0, 4), (3, 8)] {
        let m = common::with_correctives(&model(p, k), 6, 5);
        assert_eq!((m.corrective_count(), m.corrective_driver_count()), (6, 3));
        let bytes = round_trip(&m);
        // CORR: N, D, drivers, map, targets.
        let (_, length) = table_entry(&bytes, b"CORR");
        let v = m.vertex_count() as u64;
        assert_eq!(length, 4 * (2 + 3 + 6 * 9 * 3 + 6 * v * 3));
    }
    // A version-1 file (no CORR: what this format was before correctives) loads as it did.
    let m = model(3, 4);
    let v1 = legacy_file(&m, 1);
    let back = Model::from_bytes(&v1).expect("a version-1 file");
    assert_eq!(back, m);
    assert!(back.correctives().is_none() && back.corrective_count() == 0);
    let mut v0 = v1.clone();
    put_u32(&mut v0, 8, 0);
    reseal(&mut v0);
    assert_eq!(
        problem(Model::from_bytes(&v0)),
        ModelProblem::UnsupportedVersion {
            found: 0,
            supported: FORMAT_VERSION
        }
    );
}

#[test]
fn malformed_corrective_sections_are_refused() {
    let m = common::with_correctives(&model(3, 4), 4, 2);
    let bytes = m.to_bytes();
    let at = section(&bytes, b"CORR");
    let (entry, length) = table_entry(&bytes, b"CORR");
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut bad = bytes.clone();
        f(&mut bad);
        reseal(&mut bad);
        problem(Model::from_bytes(&bad))
    };
    // N and D that disagree with the section's length.
    for (word, value) in [(0, 5), (0, 0), (1, 2), (0, u32::MAX), (1, u32::MAX)] {
        let p = edit(&|b| put_u32(b, at + 4 * word, value));
        assert!(
            matches!(p, ModelProblem::SectionLength { ref tag, actual, .. } if tag == "CORR" && actual == length),
            "word {word} = {value}: {p:?}"
        );
    }
    // Shorter than its two counts.
    let p = edit(&|b| b[entry + 16..entry + 24].copy_from_slice(&4u64.to_le_bytes()));
    assert_eq!(
        p,
        ModelProblem::SectionLength {
            tag: "CORR".into(),
            expected: 8,
            actual: 4
        }
    );
    assert!(p.to_string().contains("'CORR'"), "{p}");
    // Drivers: a root, out of range, twice.
    let p = edit(&|b| put_u32(b, at + 8, 0));
    assert!(
        matches!(
            p,
            ModelProblem::BadDriver {
                index: 0,
                bone: 0,
                ..
            }
        ),
        "{p:?}"
    );
    assert!(p.to_string().contains("root"), "{p}");
    let p = edit(&|b| put_u32(b, at + 8 + 4, 9));
    assert_eq!(
        p,
        ModelProblem::IndexOutOfRange {
            what: "corrective drivers",
            index: 1,
            value: 9,
            bound: 4
        }
    );
    let first = u32::from_le_bytes(bytes[at + 8..at + 12].try_into().expect("4"));
    let p = edit(&|b| put_u32(b, at + 8 + 8, first));
    assert!(
        matches!(p, ModelProblem::BadDriver { index: 2, reason, .. } if reason.contains("twice")),
        "{p:?}"
    );
    // A NaN in the map and in the targets.
    let map = at + 8 + 4 * 3;
    let p = edit(&|b| put_u32(b, map + 4 * 7, f32::NAN.to_bits()));
    assert_eq!(
        p,
        ModelProblem::NonFinite {
            what: "corrective map",
            index: 7
        }
    );
    let targets = map + 4 * 4 * 27;
    let p = edit(&|b| put_u32(b, targets + 4 * 5, f32::INFINITY.to_bits()));
    assert_eq!(
        p,
        ModelProblem::NonFinite {
            what: "corrective targets",
            index: 5
        }
    );
}

#[test]
fn inconsistent_correctives_are_refused_by_validation() {
    let m = common::with_correctives(&model(2, 4), 3, 7);
    let v = m.vertex_count();
    let parts = m.into_parts();
    let with = |f: &dyn Fn(&mut rrskin::Correctives)| {
        let mut p = parts.clone();
        f(p.correctives.as_mut().expect("correctives"));
        problem(Model::new(p))
    };
    assert!(matches!(
        with(&|c| {
            c.targets.pop();
        }),
        ModelProblem::Length {
            what: "corrective targets (targets x vertices)",
            ..
        }
    ));
    assert!(matches!(
        with(&|c| c.targets.clear()),
        ModelProblem::Dimension {
            what: "corrective target count (N)",
            value: 0,
            ..
        }
    ));
    assert!(matches!(
        with(&|c| {
            let first = c.targets[..v].to_vec();
            c.targets = first.repeat(65);
        }),
        ModelProblem::Dimension {
            what: "corrective target count (N)",
            value: 65,
            ..
        }
    ));
    assert!(matches!(
        with(&|c| {
            c.map.pop();
        }),
        ModelProblem::Length {
            what: "corrective map (N x 9D)",
            ..
        }
    ));
    assert!(matches!(
        with(&|c| {
            c.drivers.clear();
            c.map.clear();
        }),
        ModelProblem::Dimension {
            what: "corrective driver count (D)",
            value: 0,
            ..
        }
    ));
    assert!(matches!(
        with(&|c| c.drivers[1] = c.drivers[0]),
        ModelProblem::BadDriver { index: 1, .. }
    ));
    assert!(matches!(
        with(&|c| c.drivers[0] = 0),
        ModelProblem::BadDriver {
            index: 0,
            bone: 0,
            ..
        }
    ));
    // 64 targets are the most, and valid.
    let mut most = parts.clone();
    let c = most.correctives.as_mut().expect("correctives");
    c.targets = c.targets[..v].repeat(64);
    c.map = c.map[..27].repeat(64);
    assert_eq!(Model::new(most).expect("64 targets").corrective_count(), 64);
}

/// A model of the tests' shape (J = 4, P = 5) with proxy correctives: proxies 0, 2, 3 with 1,
/// 3 and 0 drivers (4 in all), `linear` features or not and `kernels` kernels.
fn proxy_corrected(linear: bool, kernels: usize, influences: u32) -> Model {
    seeing(linear, None, kernels, influences)
}

/// [`proxy_corrected`] whose features see gravity where `up` is given.
fn seeing(linear: bool, up: Option<[f32; 3]>, kernels: usize, influences: u32) -> Model {
    let base = model(5, influences);
    let m = common::with_proxy_correctives_seeing(&base, linear, up, kernels, 3);
    let c = m.proxy_correctives().expect("proxy correctives");
    assert_eq!((c.proxies.len(), c.drivers.len()), (3, 4));
    m
}

/// The PCOR section's words: E, C, the flags, D, then E + (E + 1) + D u32, C J 9 + J (with
/// kernels) f32, 3 f32 (the up, with gravity), 24 J f32 (the ranges, with ranges), 12 D (9
/// linear + 3 gravity + C) f32.
fn pcor_words(linear: bool, gravity: bool, ranges: bool, kernels: u64) -> u64 {
    let (e, d, j) = (3, 4, 4);
    let widths = if kernels > 0 { j } else { 0 };
    let (linear, gravity) = (9 * u64::from(linear), 3 * u64::from(gravity));
    let ranges = 24 * j * u64::from(ranges);
    let maps = 12 * d * (linear + gravity + kernels);
    4 + e + e + 1 + d + kernels * j * 9 + widths + gravity + ranges + maps
}

/// `m` without feature ranges, as a file before version 6 holds it.
fn without_ranges(m: &Model) -> Model {
    let mut parts = m.parts().clone();
    parts
        .proxy_correctives
        .as_mut()
        .expect("proxy correctives")
        .ranges
        .clear();
    Model::new(parts).expect("valid")
}

#[test]
fn proxy_correctives_round_trip_and_version_2_files_still_load() {
    let up = Some([0.0, 0.6, 0.8]);
    let kinds = [
        (true, None, 0, 4),
        (false, None, 3, 8),
        (true, None, 2, 4),
        (true, up, 0, 4),
        (false, up, 2, 8),
    ];
    for (linear, up, kernels, k) in kinds {
        let ranged = seeing(linear, up, kernels, k);
        for (ranges, m) in [(true, ranged.clone()), (false, without_ranges(&ranged))] {
            assert_eq!(m.proxy_corrective_count(), 3);
            let bytes = round_trip(&m);
            let (_, length) = table_entry(&bytes, b"PCOR");
            let words = pcor_words(linear, up.is_some(), ranges, kernels as u64);
            assert_eq!(length, 4 * words);
        }
    }
    // Beside pose-space correctives.
    let both = common::with_correctives(&proxy_corrected(true, 2, 4), 3, 1);
    assert_eq!(
        Model::from_bytes(&both.to_bytes()).expect("round trip"),
        both
    );
    // A version-2 file (no PCOR: what this format was before proxy correctives, with its
    // pose-space correctives) loads as it did.
    let m = common::with_correctives(&model(3, 4), 2, 4);
    let v2 = legacy_file(&m, 2);
    let back = Model::from_bytes(&v2).expect("a version-2 file");
    assert_eq!(back, m);
    assert!(back.proxy_correctives().is_none() && back.proxy_corrective_count() == 0);
    assert_eq!(back.corrective_count(), 2);
}

#[test]
fn malformed_proxy_corrective_sections_are_refused() {
    let m = proxy_corrected(true, 2, 4);
    let bytes = m.to_bytes();
    let at = section(&bytes, b"PCOR");
    let (entry, length) = table_entry(&bytes, b"PCOR");
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut bad = bytes.clone();
        f(&mut bad);
        reseal(&mut bad);
        problem(Model::from_bytes(&bad))
    };
    // E, C, the flag and D that disagree with the section's length.
    for (word, value) in [
        (0, 5),
        (0, 0),
        (1, 3),
        (1, 0),
        (2, 0),
        (2, 1),
        (2, 7),
        (3, 5),
        (0, u32::MAX),
        (1, u32::MAX),
        (3, u32::MAX),
    ] {
        let p = edit(&|b| put_u32(b, at + 4 * word, value));
        assert!(
            matches!(p, ModelProblem::SectionLength { ref tag, actual, .. } if tag == "PCOR" && actual == length),
            "word {word} = {value}: {p:?}"
        );
    }
    let p = edit(&|b| put_u32(b, at + 8, 8));
    assert_eq!(
        p,
        ModelProblem::Dimension {
            what: "the PCOR section's feature flags",
            value: 8,
            reason: "must be 0 to 7 (bit 0 linear, bit 1 gravity, bit 2 ranges)"
        }
    );
    // Shorter than its four counts, and cut inside its arrays.
    let p = edit(&|b| b[entry + 16..entry + 24].copy_from_slice(&8u64.to_le_bytes()));
    assert_eq!(
        p,
        ModelProblem::SectionLength {
            tag: "PCOR".into(),
            expected: 16,
            actual: 8
        }
    );
    assert!(p.to_string().contains("'PCOR'"), "{p}");
    let p = edit(&|b| b[entry + 16..entry + 24].copy_from_slice(&(length - 4).to_le_bytes()));
    assert_eq!(
        p,
        ModelProblem::SectionLength {
            tag: "PCOR".into(),
            expected: length,
            actual: length - 4
        }
    );
    // The arrays' contents: proxies 0, 2, 3 at 16; offsets 0, 1, 4, 4 at 28; drivers at 44;
    // centres at 60 (2 x 4 x 9); widths at 348; ranges at 364 (4 x 24); maps at 748.
    let (proxies, offsets, drivers, centres, widths, ranges, maps) = (
        at + 16,
        at + 28,
        at + 44,
        at + 60,
        at + 348,
        at + 364,
        at + 748,
    );
    assert_eq!(
        at + 4 * pcor_words(true, false, true, 2) as usize,
        maps + 4 * 12 * 4 * 11
    );
    // Joint 1's upper bound of φ entry 0 (its range's word 12) below 0.
    assert!(matches!(
        edit(&|b| b[ranges + 4 * (24 + 12)..][..4].copy_from_slice(&(-0.5f32).to_le_bytes())),
        ModelProblem::BadProxyCorrective {
            what: "ranges",
            index: 1,
            ..
        }
    ));
    assert_eq!(
        edit(&|b| put_u32(b, proxies + 8, 5)),
        ModelProblem::IndexOutOfRange {
            what: "proxy corrective proxies",
            index: 2,
            value: 5,
            bound: 5
        }
    );
    let p = edit(&|b| put_u32(b, proxies + 4, 3));
    assert!(
        matches!(
            p,
            ModelProblem::BadProxyCorrective {
                what: "proxies",
                index: 2,
                ..
            }
        ),
        "{p:?}"
    );
    let p = edit(&|b| put_u32(b, offsets + 8, 0));
    assert!(
        matches!(p, ModelProblem::BadProxyCorrective { what: "driver offsets", index: 2, reason } if reason.contains("below")),
        "{p:?}"
    );
    let p = edit(&|b| put_u32(b, offsets, 1));
    assert!(
        matches!(
            p,
            ModelProblem::BadProxyCorrective {
                what: "driver offsets",
                index: 0,
                ..
            }
        ),
        "{p:?}"
    );
    let p = edit(&|b| put_u32(b, offsets + 12, 5));
    assert!(
        matches!(p, ModelProblem::Length { what, expected: 5, actual: 4 } if what.contains("last driver offset")),
        "{p:?}"
    );
    let p = edit(&|b| put_u32(b, drivers, 0));
    assert!(
        matches!(p, ModelProblem::BadProxyDriver { proxy: 0, index: 0, bone: 0, reason } if reason.contains("root")),
        "{p:?}"
    );
    assert!(p.to_string().contains("proxy 0"), "{p}");
    let second = u32::from_le_bytes(bytes[drivers + 4..drivers + 8].try_into().expect("4"));
    let p = edit(&|b| put_u32(b, drivers + 8, second));
    assert!(
        matches!(p, ModelProblem::BadProxyDriver { proxy: 2, index: 1, reason, .. } if reason.contains("twice")),
        "{p:?}"
    );
    assert_eq!(
        edit(&|b| put_u32(b, drivers + 12, 4)),
        ModelProblem::IndexOutOfRange {
            what: "proxy corrective drivers",
            index: 3,
            value: 4,
            bound: 4
        }
    );
    assert_eq!(
        edit(&|b| put_u32(b, centres + 4 * 10, f32::NAN.to_bits())),
        ModelProblem::NonFinite {
            what: "proxy corrective kernel centres",
            index: 10
        }
    );
    let driver = u32::from_le_bytes(bytes[drivers..drivers + 4].try_into().expect("4"));
    let p = edit(&|b| put_u32(b, widths + 4 * driver as usize, 0.0f32.to_bits()));
    assert!(
        matches!(p, ModelProblem::BadProxyCorrective { what: "widths", index, .. } if index == driver as usize),
        "{p:?}"
    );
    // The root drives nothing: its width may be anything finite.
    let mut ok = bytes.clone();
    put_u32(&mut ok, widths, (-1.0f32).to_bits());
    reseal(&mut ok);
    Model::from_bytes(&ok).expect("a root's width is not used");
    assert_eq!(
        edit(&|b| put_u32(b, widths, f32::INFINITY.to_bits())),
        ModelProblem::NonFinite {
            what: "proxy corrective kernel widths",
            index: 0
        }
    );
    assert_eq!(
        edit(&|b| put_u32(b, maps + 4 * 100, f32::NAN.to_bits())),
        ModelProblem::NonFinite {
            what: "proxy corrective maps",
            index: 100
        }
    );
}

#[test]
fn inconsistent_proxy_correctives_are_refused_by_validation() {
    let parts = proxy_corrected(true, 2, 4).into_parts();
    let with = |f: &dyn Fn(&mut rrskin::ProxyCorrectives)| {
        let mut p = parts.clone();
        f(p.proxy_correctives.as_mut().expect("proxy correctives"));
        problem(Model::new(p))
    };
    let dimension = |p: ModelProblem| match p {
        ModelProblem::Dimension { what, value, .. } => (what, value),
        p => panic!("not a Dimension: {p:?}"),
    };
    let length = |p: ModelProblem| match p {
        ModelProblem::Length { what, .. } => what,
        p => panic!("not a Length: {p:?}"),
    };
    let none = with(&|c| {
        c.proxies.clear();
        c.driver_offsets = vec![0];
        c.drivers.clear();
        c.maps.clear();
    });
    assert_eq!(dimension(none), ("corrected proxy count (E)", 0));
    assert_eq!(
        dimension(with(&|c| c.proxies = (0..6).collect())),
        ("corrected proxy count (E)", 6)
    );
    // A plain LBS model has no proxies to correct.
    let mut lbs = parts.clone();
    (lbs.keys, lbs.c1, lbs.c2) = (Vec::new(), Vec::new(), Vec::new());
    lbs.skin_indices.iter_mut().for_each(|i| *i %= 4);
    assert_eq!(
        dimension(problem(Model::new(lbs))),
        ("corrected proxy count (E)", 3)
    );
    assert!(length(with(&|c| {
        c.driver_offsets.pop();
    }))
    .contains("driver offsets"));
    let many = with(&|c| {
        let d = 33;
        c.driver_offsets = vec![0, d, d, d];
        c.drivers = vec![1; d as usize];
    });
    assert!(
        matches!(many, ModelProblem::BadProxyCorrective { what: "driver offsets", index: 1, reason } if reason.contains("32")),
        "{many:?}"
    );
    assert!(length(with(&|c| {
        c.centres.pop();
    }))
    .contains("centres"));
    let too_many = with(&|c| {
        c.centres = vec![[0.0; 9]; 4 * 257];
        c.maps = vec![0.0; 12 * 4 * (9 + 257)];
    });
    assert_eq!(
        dimension(too_many),
        ("proxy corrective kernels per joint (C)", 257)
    );
    assert!(length(with(&|c| {
        c.widths.pop();
    }))
    .contains("widths"));
    // No kernels: no widths either.
    assert!(length(with(&|c| {
        c.centres.clear();
        c.maps = vec![0.0; 12 * 4 * 9];
    }))
    .contains("widths"));
    let nothing = with(&|c| {
        c.linear = false;
        c.centres.clear();
        c.widths.clear();
        c.maps.clear();
    });
    assert_eq!(
        dimension(nothing),
        (
            "proxy corrective features per driver (9 linear + 3 gravity + C)",
            0
        )
    );
    assert!(length(with(&|c| {
        c.maps.pop();
    }))
    .contains("maps"));
    assert!(matches!(
        with(&|c| c.widths[c.drivers[0] as usize] = -1.0),
        ModelProblem::BadProxyCorrective { what: "widths", .. }
    ));
    // 32 drivers per proxy and 256 kernels are the most, and valid (drivers may repeat across
    // proxies, not within one).
    let mut most = parts.clone();
    let c = most.proxy_correctives.as_mut().expect("proxy correctives");
    c.centres = vec![[0.1; 9]; 4 * 256];
    c.maps = vec![0.0; 12 * 4 * (9 + 256)];
    Model::new(most).expect("256 kernels");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Arbitrary edits of the PCOR section, resealed (so past the checksum: what a buggy writer
    /// could make), never panic: the file is refused with a BadModel, or the model it gives
    /// evaluates on the CPU and in the palette.
    #[test]
    fn resealed_edits_of_proxy_correctives_never_panic(at in 0usize..2476, junk in proptest::collection::vec(any::<u8>(), 1..12)) {
        let good = proxy_corrected(true, 2, 4).to_bytes();
        let start = section(&good, b"PCOR");
        let mut bytes = good.clone();
        for (i, b) in junk.iter().enumerate() {
            if at + i < 2476 {
                bytes[start + at + i] = *b;
            }
        }
        reseal(&mut bytes);
        match Model::from_bytes(&bytes) {
            Ok(m) => {
                let bones = rrskin_render::synthetic::random_poses(&m, 2, 1);
                let n = 2 * m.vertex_count();
                let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
                rrskin::cpu::CpuEvaluator::new(&m).evaluate(&bones, &mut p, &mut nrm).expect("CPU");
                let palette = rrskin::palette::Palette::new(m.clone()).expect("palette");
                let mut out = vec![[0.0; 12]; 2 * palette.len()];
                palette.compute_batch(&bones, &mut out).expect("palette");
            }
            Err(Error::BadModel { .. }) => {}
            Err(other) => prop_assert!(false, "unexpected error kind {:?}", other),
        }
    }
}

/// A model of the tests' shape (J = 4, P = 5) whose keys 0, 1 and 3 are delta-mush keys.
fn with_delta_mush(influences: u32) -> Model {
    let m = common::with_delta_mush_keys(&model(5, influences), 3, 5).expect("3 of 5 keys");
    let kinds: Vec<KeyKind> = m.keys().iter().map(Key::kind).collect();
    use KeyKind::{DeltaMush, Predictor};
    assert_eq!(
        kinds,
        [DeltaMush, DeltaMush, Predictor, DeltaMush, Predictor]
    );
    m
}

/// [`with_delta_mush`]'s delta-mush keys after two predictors, as files before version 8 order them.
fn with_delta_mush_last(influences: u32) -> Model {
    let mut parts = model(5, influences).into_parts();
    parts.keys.truncate(2);
    parts.keys.extend(
        with_delta_mush(influences)
            .keys()
            .iter()
            .filter(|k| k.delta_mush().is_some())
            .cloned(),
    );
    Model::new(parts).expect("valid")
}

#[test]
fn keys_of_both_kinds_round_trip_in_any_order() {
    for k in [4, 8] {
        let m = with_delta_mush(k);
        let bytes = round_trip(&m);
        // KEYS: P + 1 offsets, then per key its tag and its words (85, or 13 a term).
        let terms: usize = m
            .keys()
            .iter()
            .filter_map(Key::delta_mush)
            .map(|k| k.terms.len())
            .sum();
        let words = 6 + 5 + 2 * 85 + 13 * terms;
        assert_eq!(table_entry(&bytes, b"KEYS").1, 4 * words as u64);
        for tag in [b"PRED", b"MUSH"] {
            assert!(sections(&bytes).iter().all(|(t, _)| t != tag), "no {tag:?}");
        }
    }
    // Beside both correctives.
    let all = common::with_proxy_correctives(
        &common::with_correctives(&with_delta_mush(4), 2, 1),
        true,
        1,
        2,
    );
    round_trip(&all);
    // A version-3 file (no MUSH: what this format was before delta-mush keys) loads as it did.
    let m = proxy_corrected(true, 2, 4);
    assert_eq!(
        Model::from_bytes(&legacy_file(&m, 3)).expect("a version-3 file"),
        m
    );
}

#[test]
fn version_7_files_load_as_the_same_model() {
    let m = with_delta_mush_last(4);
    let v7 = legacy_file(&m, 7);
    assert!(sections(&v7).iter().any(|(t, _)| t == b"MUSH"));
    let loaded = Model::from_bytes(&v7).expect("a version-7 file");
    assert_eq!(loaded, m);
    assert_ne!(loaded.to_bytes(), v7, "saved again, it is a version-8 file");
}

/// The exact rotation nearest to `a` (det > 0, row-major): Newton's iteration on matrices,
/// R ← (R + R⁻ᵀ) / 2 (Higham 1986), run to convergence.
fn exact_polar(a: [[f64; 3]; 3]) -> glam::DMat3 {
    let a = glam::DMat3::from_cols_array_2d(&a).transpose();
    (0..60).fold(a, |r, _| (r + r.inverse().transpose()) * 0.5)
}

#[test]
fn version_6_delta_mush_keys_load_into_their_frames_as_the_same_model() {
    // Files before version 7 stored the keys' terms unturned, for the exact polar rotation.
    let m = with_delta_mush_last(4);
    let loaded = Model::from_bytes(&legacy_file(&m, 6)).expect("a version-6 file");
    assert_ne!(loaded.parts().c1, m.parts().c1, "C1 turned with the keys");
    // Every key's D, read as C1 reads it (the fit turned out of its frame), is the exact polar
    // rotation the version-6 model was trained for, to the fit's accuracy: random keys under
    // random poses are far from rigid (3e-5 measured; keys of trained models, 5e-9 on average).
    let mut worst: f64 = 0.0;
    for pose in 0..8 {
        let bones = rrskin_render::synthetic::random_poses(&m, 1, pose);
        for (old, new) in m.keys().iter().zip(loaded.keys()) {
            let (Some(old), Some(new)) = (old.delta_mush(), new.delta_mush()) else {
                assert_eq!(old, new, "a predictor stays as it is");
                continue;
            };
            let (turned, frame) = old.in_principal_frame();
            assert_eq!(new, &turned);
            let exact = exact_polar(rrskin::predict::delta_mush_covariance(old, &bones));
            let frame = glam::DMat3::from_cols_array_2d(&frame).transpose();
            let d = rrskin::predict::delta_mush_gradient(new, &bones) * frame.transpose();
            worst = worst.max(
                (d - exact)
                    .to_cols_array()
                    .iter()
                    .fold(0.0, |w, x| w.max(x.abs())),
            );
        }
    }
    assert!(worst < 1e-4, "{worst}");
    // Saved again, it is a version-8 file, and loads unturned a second time.
    let back = Model::from_bytes(&loaded.to_bytes()).expect("round trip");
    assert_eq!(back, loaded);
}

#[test]
fn malformed_delta_mush_sections_of_version_7_are_refused() {
    let bytes = legacy_file(&with_delta_mush_last(4), 7);
    let at = section(&bytes, b"MUSH");
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut bad = bytes.clone();
        f(&mut bad);
        reseal(&mut bad);
        problem(Model::from_bytes(&bad))
    };
    // More keys or bones than the section holds.
    for (word, value) in [(0, 4), (1, 1000)] {
        let p = edit(&|b| put_u32(b, at + 4 * word, value));
        assert!(
            matches!(&p, ModelProblem::SectionLength { tag, .. } if tag == "MUSH"),
            "{p:?}"
        );
    }
    // More delta-mush keys than DIMS's P = 5 keys, the section's length kept: S = 16 and one
    // bone fewer take as many words (13 a bone); offsets that run backwards.
    let n = le_u32(&bytes, at + 4);
    let p = edit(&|b| {
        put_u32(b, at, 16);
        put_u32(b, at + 4, n - 1);
        (0..17).for_each(|i| put_u32(b, at + 8 + 4 * i, (i as u32).min(n - 1)));
    });
    assert!(
        matches!(
            p,
            ModelProblem::Dimension {
                what: "the MUSH section's key count",
                value: 16,
                ..
            }
        ),
        "{p:?}"
    );
    let p = edit(&|b| put_u32(b, at + 12, n + 1));
    assert!(
        matches!(
            p,
            ModelProblem::Dimension {
                what: "the MUSH section's offsets",
                ..
            }
        ),
        "{p:?}"
    );
}

#[test]
fn malformed_key_records_are_refused() {
    let bytes = with_delta_mush(4).to_bytes();
    let edit = |at: usize, value: u32| {
        let mut bad = bytes.clone();
        put_u32(&mut bad, at, value);
        reseal(&mut bad);
        problem(Model::from_bytes(&bad))
    };
    let keys = section(&bytes, b"KEYS");
    // A kind this build does not know (key 2's tag, the word before its record).
    let p = edit(key_word(&bytes, 2, 0) - 4, 7);
    assert_eq!(
        p,
        ModelProblem::BadKey {
            key: 2,
            reason: "has a kind this build does not know"
        }
    );
    // Key 2, a predictor, a word short (key 1 a word longer: not whole terms).
    let p = edit(keys + 8, le_u32(&bytes, keys + 8) + 1);
    assert!(matches!(p, ModelProblem::BadKey { key: 1, .. }), "{p:?}");
    let p = edit(keys, 7);
    assert!(
        matches!(
            p,
            ModelProblem::Dimension {
                what: "the KEYS section's offsets",
                ..
            }
        ),
        "{p:?}"
    );
}

#[test]
fn inconsistent_delta_mush_keys_are_refused_by_validation() {
    let parts = with_delta_mush(4).into_parts();
    // Key 1, a delta-mush key, edited.
    let with = |f: &dyn Fn(&mut DeltaMushKey)| {
        let mut p = parts.clone();
        match &mut p.keys[1] {
            Key::DeltaMush(k) => f(k),
            Key::Predictor(_) => unreachable!("key 1 is a delta-mush key"),
        }
        problem(Model::new(p))
    };
    let bad = |p: ModelProblem| match p {
        ModelProblem::BadKey { key, reason } => (key, reason),
        p => panic!("not a BadKey: {p:?}"),
    };
    let empty = with(&|k| k.terms.clear());
    assert_eq!(bad(empty), (1, "is a delta-mush key without a bone"));
    let term = |bone| DeltaMushTerm {
        bone,
        omega: [0.5; 12],
    };
    assert_eq!(
        bad(with(&|k| k.terms = vec![term(1), term(2), term(1)])),
        (1, "lists a bone twice")
    );
    let many = with(&|k| k.terms = (0..257).map(|b| term(b % 4)).collect());
    assert!(bad(many).1.contains("256"));
    let p = with(&|k| k.terms[0].bone = 4);
    assert!(
        matches!(
            p,
            ModelProblem::IndexOutOfRange {
                what: "delta-mush key bone",
                index: 1,
                bound: 4,
                ..
            }
        ),
        "{p:?}"
    );
    let p = with(&|k| k.terms[0].omega[5] = f32::NAN);
    assert_eq!(
        p,
        ModelProblem::NonFinite {
            what: "delta-mush key terms",
            index: 1
        }
    );
}
