//! A mutation campaign over the input loaders, as tests/model_file.rs runs over `.rrs` files:
//! NPY example sets, glTF/GLB rigs, PC2/MDD point caches. Each seed file (a valid input) is cut,
//! bit-flipped, spliced with its own bytes, and has integers (binary, and digits in the text of
//! NPY headers and glTF JSON) replaced by extreme values. Every mutant must end in an error or
//! a valid result: no panic, no hang (a mutant over `HANG_SECONDS`), no unbounded memory (a
//! mutant's allocations past `MEMORY_LIMIT`, counted by this binary's allocator).
//!
//! In the suite: `MUTANTS` per seed file. At a large count (the documented command):
//!
//!     RRSKIN_FUZZ_MUTANTS=20000 cargo test --release -p rrskin-tools --test loader_fuzz
//!
//! `RRSKIN_FUZZ_SEED` varies the campaign (a failure names it, the file and the mutant);
//! `RRSKIN_FUZZ_VERBOSE=1` prints every mutant first (to find one that aborts the process).

mod support;

use rrskin_tools::import::gltf::{import, Options};
use rrskin_tools::import::point_cache::PointCache;
use rrskin_tools::set::ExampleSet;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

const MUTANTS: usize = 120;
const HANG_SECONDS: u64 = 20;
/// Allocations live at once during one mutant, past which it counts as unbounded; one request
/// past `REFUSED` is not attempted (the process aborts, naming its size).
const MEMORY_LIMIT: usize = 512 << 20;
const REFUSED: usize = 4 << 30;

/// Counts each thread's live heap bytes, and their peak, so a campaign can bound a mutant's.
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn count(delta: isize) {
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

// SAFETY: forwards to the system allocator; the bookkeeping neither allocates nor unwinds.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSED {
            return std::ptr::null_mut();
        }
        count(layout.size() as isize);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count(-(layout.size() as isize));
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > REFUSED {
            return std::ptr::null_mut();
        }
        // SAFETY: as above.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            count(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The heap bytes `f` had live at most at once, above what its thread held before.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    (out, (PEAK.with(Cell::get) - base).max(0) as usize)
}

/// splitmix64: reproducible mutants without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const EXTREME_WORDS: [u64; 10] = [
    0,
    1,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0x1_0000_0000,
    0x7FFF_FFFF_FFFF_FFFF,
    0x8000_0000_0000_0000,
    u64::MAX,
    0xFFFF_FFFF_FFFF_FFFE,
];
const EXTREME_TEXT: [&str; 9] = [
    "0",
    "-1",
    "4294967296",
    "2147483648",
    "9223372036854775807",
    "18446744073709551615",
    "99999999999999999999999999",
    "1e308",
    "-9223372036854775808",
];

/// One mutant of `seed`: half of the edits land in `hot` (the header or the JSON, where the
/// structure is), the rest anywhere. Returns the bytes and what was done.
fn mutate(rng: &mut Rng, seed: &[u8], hot: &Range<usize>) -> (Vec<u8>, String) {
    let mut b = seed.to_vec();
    let n = b.len().max(1);
    let at = |rng: &mut Rng| match rng.below(2) {
        0 if hot.end > hot.start => hot.start + rng.below(hot.end - hot.start),
        _ => rng.below(n),
    };
    match rng.below(6) {
        0 => {
            let cut = at(rng).min(b.len());
            b.truncate(cut);
            (b, format!("truncated to {cut} bytes"))
        }
        1 => {
            let flips = 1 + rng.below(8);
            let mut places = Vec::new();
            for _ in 0..flips {
                let i = at(rng).min(b.len().saturating_sub(1));
                let bit = rng.below(8);
                if let Some(x) = b.get_mut(i) {
                    *x ^= 1 << bit;
                }
                places.push((i, bit));
            }
            (b, format!("bits flipped at (byte, bit) {places:?}"))
        }
        2 => {
            // Splice: a run of the file's own bytes copied over, or inserted at, another place.
            let (from, to) = (rng.below(n), at(rng));
            let len = 1 + rng.below(64);
            let run: Vec<u8> = seed.iter().skip(from).take(len).copied().collect();
            let insert = rng.below(2) == 0;
            let to = to.min(b.len());
            if insert {
                b.splice(to..to, run.iter().copied());
            } else {
                let end = (to + run.len()).min(b.len());
                b.splice(to..end, run.iter().copied());
            }
            let verb = if insert { "inserted" } else { "copied over" };
            (b, format!("{} bytes from {from} {verb} {to}", run.len()))
        }
        3 => {
            let (start, len) = (at(rng).min(b.len()), 1 + rng.below(256));
            let end = (start + len).min(b.len());
            b.drain(start..end);
            (b, format!("bytes {start}..{end} deleted"))
        }
        4 => {
            let value = EXTREME_WORDS[rng.below(EXTREME_WORDS.len())];
            let (width, big) = ([4, 8][rng.below(2)], rng.below(2) == 0);
            let i = at(rng).min(b.len().saturating_sub(width));
            let bytes = if big {
                value.to_be_bytes()[8 - width..].to_vec()
            } else {
                value.to_le_bytes()[..width].to_vec()
            };
            let end = (i + width).min(b.len());
            b.splice(i..end, bytes);
            let order = if big { "big" } else { "little" };
            (b, format!("{width}-byte {order}-endian {value:#x} at {i}"))
        }
        _ => {
            // A decimal number in the text (NPY header, glTF JSON) replaced by an extreme one.
            let digits: Vec<usize> = (hot.start..hot.end.min(b.len()))
                .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit()))
                .collect();
            if digits.is_empty() {
                return mutate(rng, seed, &(0..0));
            }
            let start = digits[rng.below(digits.len())];
            let end = (start..b.len())
                .find(|&i| !b[i].is_ascii_digit())
                .unwrap_or(b.len());
            let text = EXTREME_TEXT[rng.below(EXTREME_TEXT.len())];
            b.splice(start..end, text.bytes());
            (b, format!("number at {start} replaced by {text}"))
        }
    }
}

/// A seed file: its name, its bytes, where its structure is.
struct Seed {
    name: String,
    bytes: Vec<u8>,
    hot: Range<usize>,
}

/// Runs `per_seed` mutants of every seed through `load` (any result but a panic is fine), on a
/// worker thread watched for hangs; returns every failure, described.
fn campaign(seeds: Vec<Seed>, load: impl Fn(&Seed, &[u8]) + Send + 'static) -> Vec<String> {
    let per_seed = std::env::var("RRSKIN_FUZZ_MUTANTS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(MUTANTS);
    let seed_value: u64 = std::env::var("RRSKIN_FUZZ_SEED")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1);
    let verbose = std::env::var_os("RRSKIN_FUZZ_VERBOSE").is_some();
    let (tx, rx) = mpsc::channel::<Option<String>>();
    quiet_panics();
    let worker = std::thread::Builder::new()
        .name(WORKER.into())
        .spawn(move || {
            for (s, seed) in seeds.iter().enumerate() {
                let mut rng = Rng(seed_value ^ ((s as u64) << 32));
                for m in 0..per_seed {
                    let (bytes, what) = mutate(&mut rng, &seed.bytes, &seed.hot);
                    let name = format!(
                        "{} mutant {m} (RRSKIN_FUZZ_SEED={seed_value}): {what}",
                        seed.name
                    );
                    if verbose {
                        eprintln!("{name}");
                    }
                    let (outcome, peak) = peak_of(|| {
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                            load(seed, &bytes)
                        }))
                    });
                    let failure = match outcome {
                        Err(payload) => {
                            let message = payload
                                .downcast_ref::<&str>()
                                .map(|s| s.to_string())
                                .or_else(|| payload.downcast_ref::<String>().cloned())
                                .unwrap_or_default();
                            Some(format!("{name}: panicked: {message}"))
                        }
                        Ok(()) if peak > MEMORY_LIMIT => {
                            Some(format!("{name}: {peak} bytes live at once"))
                        }
                        Ok(()) => None,
                    };
                    if tx.send(failure.or(Some(String::new()))).is_err() {
                        return;
                    }
                }
            }
            let _ = tx.send(None);
        });
    let Ok(worker) = worker else {
        return vec!["cannot start the worker thread".into()];
    };
    let mut failures = Vec::new();
    loop {
        match rx.recv_timeout(Duration::from_secs(HANG_SECONDS)) {
            Ok(Some(f)) if f.is_empty() => {}
            Ok(Some(f)) => failures.push(f),
            Ok(None) => break,
            Err(_) => {
                failures.push(format!(
                    "a mutant ran past {HANG_SECONDS} s (rerun with RRSKIN_FUZZ_VERBOSE=1: the last one printed)"
                ));
                return failures;
            }
        }
    }
    let _ = worker.join();
    failures
}

fn assert_none(failures: Vec<String>) {
    assert!(
        failures.is_empty(),
        "{} mutants failed; the first:\n{}",
        failures.len(),
        failures[..failures.len().min(10)].join("\n")
    );
}

fn data(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(path)
}

/// The campaign's worker thread, whose panics are findings reported at the end, not a message
/// per mutant.
const WORKER: &str = "fuzz-worker";

fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if std::thread::current().name() != Some(WORKER) {
                default(info);
            }
        }));
    });
}

#[test]
fn npy_example_sets_never_panic() {
    // CesiumMan's folder cut to 3 poses (2 train, 1 test), and the rig's weights, so that every
    // file of the layout is a seed.
    let full = ExampleSet::load(data("cesiumman")).expect("the bundled set");
    let mut set = full.clone();
    set.poses.truncate(3);
    set.is_test = vec![false, false, true];
    set.rig_weights = Some(vec![vec![(0, 1.0)]; set.vertex_count()]);
    let seed_dir = support::temp_dir("fuzz-npy-seed");
    set.save(&seed_dir).expect("save");
    let files = [
        "rest_vertices.npy",
        "faces.npy",
        "bone_parents.npy",
        "pose_transforms.npy",
        "pose_vertices.npy",
        "split.npy",
        "skin_weights.npy",
    ];
    let seeds = files
        .iter()
        .map(|f| {
            let bytes = std::fs::read(seed_dir.join(f)).expect("seed");
            Seed {
                name: f.to_string(),
                hot: 0..128.min(bytes.len()),
                bytes,
            }
        })
        .collect();
    let work = support::temp_dir("fuzz-npy");
    for f in files {
        std::fs::copy(seed_dir.join(f), work.join(f)).expect("copy");
    }
    let dir = work.to_path_buf();
    let failures = campaign(seeds, move |seed, bytes| {
        let path = dir.join(&seed.name);
        std::fs::write(&path, bytes).expect("write mutant");
        let _ = ExampleSet::load(&dir);
        std::fs::write(&path, &seed.bytes).expect("restore");
    });
    assert_none(failures);
}

/// The CesiumMan rig (structure in its JSON chunk) with a cache of its first 4 samples: mutants
/// of the GLB, and of the cache as PC2 and as MDD, imported together.
#[test]
fn gltf_rigs_and_point_caches_never_panic() {
    let glb = std::fs::read(data("cesiumman_gltf/CesiumMan_examples.glb")).expect("rig");
    let good =
        PointCache::load(&data("cesiumman_gltf/CesiumMan_examples.pc2"), 24.0).expect("cache");
    let short = PointCache {
        format: good.format,
        frames: good.frames[..4].to_vec(),
        times: good.times[..4].to_vec(),
        positions: good.positions[..4].to_vec(),
    };
    // GLB: 12-byte header, then the JSON chunk's 8-byte header and text.
    let json_end = 20 + u32::from_le_bytes([glb[12], glb[13], glb[14], glb[15]]) as usize;
    let (pc2, mdd) = (short.to_pc2(), short.to_mdd());
    let seeds = vec![
        Seed {
            name: "rig.glb".into(),
            hot: 0..json_end.min(glb.len()),
            bytes: glb.clone(),
        },
        Seed {
            name: "cache.pc2".into(),
            hot: 0..32,
            bytes: pc2.clone(),
        },
        Seed {
            name: "cache.mdd".into(),
            hot: 0..8 + 4 * 4,
            bytes: mdd.clone(),
        },
    ];
    let dir = support::temp_dir("fuzz-gltf");
    let valid = [("rig.glb", glb), ("cache.pc2", pc2), ("cache.mdd", mdd)];
    for (name, bytes) in &valid {
        std::fs::write(dir.join(name), bytes).expect("write seed");
    }
    let work = dir.to_path_buf();
    let failures = campaign(seeds, move |seed, bytes| {
        let path = work.join(&seed.name);
        std::fs::write(&path, bytes).expect("write mutant");
        let cache = if seed.name == "cache.mdd" {
            "cache.mdd"
        } else {
            "cache.pc2"
        };
        let options = Options {
            clip: "examples".into(),
            cache: work.join(cache),
            fps: 24.0,
            test_frames: Some((2.0, 3.0)),
        };
        let _ = import(&work.join("rig.glb"), &options);
        std::fs::write(&path, &seed.bytes).expect("restore");
    });
    assert_none(failures);
}

/// The campaign finds what it looks for: a loader that panics on some mutants is reported.
#[test]
fn the_campaign_reports_a_panicking_loader() {
    let seeds = vec![Seed {
        name: "bytes".into(),
        bytes: vec![7; 64],
        hot: 0..8,
    }];
    let failures = campaign(seeds, |_, bytes| {
        assert!(bytes.len() == 64, "resized");
    });
    assert!(
        failures
            .iter()
            .any(|f| f.contains("bytes mutant") && f.contains("panicked")),
        "{failures:?}"
    );
}
