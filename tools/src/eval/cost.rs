//! A model's predicted run-time cost ([`rrskin::cost`]) as `rrskin info`, `train` and `eval`
//! report it: per target, the passes' work a character and the prediction.

use rrskin::cost::{Cost, Target, Work, LAVAPIPE};
use rrskin::Model;

/// `model`'s cost on every target of the calibrated device, as JSON (`cost`): per target the
/// predicted ns a character, the ratio to the engine baseline (Vulkan frames) and every pass's
/// work.
pub fn to_json(model: &Model) -> serde_json::Value {
    let targets: serde_json::Map<String, serde_json::Value> = (Target::ALL.iter())
        .map(|&t| {
            let c = Cost::of(model, t, &LAVAPIPE);
            let passes = (c.passes.iter())
                .map(|p| work_json(p.pass, p.work))
                .collect::<Vec<_>>();
            let json = serde_json::json!({
                "ns": c.ns, "us": c.microseconds(), "engine_ns": c.engine_ns, "ratio": c.ratio(),
                "passes": passes, "engine": c.engine.map(|w| work_json("engine", w)),
            });
            (t.name().to_string(), json)
        })
        .collect();
    serde_json::json!({"device": LAVAPIPE.name, "targets": targets})
}

/// One line: the two frames over the engine baseline and the CPU palette's µs a character.
pub fn line(model: &Model) -> String {
    let cost = |t| Cost::of(model, t, &LAVAPIPE);
    let ratio = |t| cost(t).ratio().unwrap_or(f64::NAN);
    format!(
        "predicted cost ({}): {:.2} x the engine baseline with recomputed normals, {:.2} x with transformed normals; CPU palette {:.1} us a character",
        LAVAPIPE.name,
        ratio(Target::Recomputed),
        ratio(Target::Transformed),
        cost(Target::Palette).microseconds()
    )
}

fn work_json(pass: &str, w: Work) -> serde_json::Value {
    serde_json::json!({
        "pass": pass, "groups": w.groups, "bytes": w.bytes, "loads": w.loads, "gathers": w.gathers, "streams": w.streams, "madds": w.madds, "specials": w.specials,
    })
}
