//! A model's dimensions and predicted cost, as `rrskin info --json` and the Python package's
//! `Model.info` give them.

use rrskin::Model;

/// `model`'s dimensions (V, T, J, P and its delta-mush keys, K, the correctives), whether it
/// has rest tangents, sees gravity or clamps its features, and its `cost`
/// ([`crate::eval::cost::to_json`]).
pub fn to_json(m: &Model) -> serde_json::Value {
    let clamped = m.proxy_correctives().is_some_and(|c| !c.ranges.is_empty());
    serde_json::json!({
        "vertices": m.vertex_count(), "triangles": m.triangle_count(),
        "bones": m.bone_count(), "proxies": m.proxy_count(), "influences": m.influences(),
        "tangents": m.has_tangents(), "correctives": m.corrective_count(),
        "proxy_correctives": m.proxy_corrective_count(),
        "delta_mush_keys": m.keys_of(rrskin::KeyKind::DeltaMush), "up": m.up(),
        "clamped": clamped, "cost": crate::eval::cost::to_json(m),
    })
}
