//! The least memory traffic of a frame, and so its bandwidth bound: what `rrskin bench` and
//! `rrskin profile` compare the measured frame with. C characters, V vertices, T triangles,
//! J bones, P proxies, K influences, 4-byte floats and indices:
//!
//! ```text
//! bones in                         48 C J
//! B = [d; q] (two-pass product)    2 · 12 C (3P + 4J)   written by pass 1, read by pass 2
//! palette [t; q] (P > 0)           2 · 48 C (P + J)     written by the product, read by skinning
//! skinning                         12 V + 8 K V         rest and weights, once for all characters
//!                                  + 12 C V             positions written
//! recomputed normals               12 C V + 12 C V      positions read, normals written
//!                                  + 4 (V + 1) + 4 F    1-ring fans (F entries, ~3T + 2V), once
//!   tangents (option)              16 V + 8 K V + 48 C (P + J) + 12 C V + 16 C V
//! transformed normals, in skinning 12 V + 12 C V        rest normals, normals written
//!   tangents (option)              16 V + 16 C V        rest tangents, tangents written
//! bounds (option)                  12 C V + 32 C
//! ```
//!
//! Every per-character array is read or written once, every model array read once (its reuse
//! across characters is the caches'), the model's C1/C2 and predictors left out (a few KB).
//! The bound is these bytes over the device's peak bandwidth; the fraction of it a frame
//! reaches is bound / measured time.

use rrskin::vk::CrowdOptions;
use rrskin::{Model, NormalMode};

/// The bytes above for a crowd of `characters` of `model` made with `options`; `fused`: the
/// product evaluates the predictors itself (no B round trip).
pub fn frame_bytes(model: &Model, characters: usize, options: &CrowdOptions, fused: bool) -> u64 {
    let (c, v, fans) = (
        characters as u64,
        model.vertex_count() as u64,
        model.normal_fans().entries.len() as u64,
    );
    let (j, p, k) = (
        model.bone_count() as u64,
        model.proxy_count() as u64,
        model.influences() as u64,
    );
    let palette = if p > 0 { 48 * c * (p + j) } else { 0 };
    let rhs = if p > 0 && !fused {
        2 * 12 * c * (3 * p + 4 * j)
    } else {
        0
    };
    let skinning = 12 * v + 8 * k * v + 12 * c * v;
    let tangents = u64::from(options.tangents);
    let normals = match options.normals {
        NormalMode::Recomputed => {
            24 * c * v
                + 4 * (v + 1 + fans)
                + tangents * (16 * v + 8 * k * v + 48 * c * (p + j) + 28 * c * v)
        }
        NormalMode::Transformed => 12 * v + 12 * c * v + tangents * (16 * v + 16 * c * v),
    };
    let bounds = if options.bounds {
        12 * c * v + 32 * c
    } else {
        0
    };
    48 * c * j + rhs + 2 * palette + skinning + normals + bounds
}

#[cfg(test)]
mod tests {
    use super::*;
    use rrskin_render::synthetic::{random_model, Spec};

    /// Each term counts where the module says: the two-pass product's B round trip, the
    /// palette, the options; and a plain LBS crowd moves no palette.
    #[test]
    fn the_bytes_follow_the_table() {
        let spec = Spec {
            grid: 6,
            bones: 5,
            proxies: 3,
            influences: 4,
        };
        let rr = random_model(spec, 1).expect("valid");
        let lbs = random_model(Spec { proxies: 0, ..spec }, 1).expect("valid");
        let (c, v, j, p) = (7u64, 36u64, 5u64, 3u64);
        let plain = CrowdOptions::default();
        let bytes = |m: &Model, o: &CrowdOptions, fused| frame_bytes(m, c as usize, o, fused);
        assert_eq!(
            bytes(&rr, &plain, false) - bytes(&rr, &plain, true),
            24 * c * (3 * p + 4 * j)
        );
        assert_eq!(
            bytes(&rr, &plain, true) - bytes(&lbs, &plain, true),
            96 * c * (p + j)
        );
        let bounded = CrowdOptions {
            bounds: true,
            ..plain
        };
        assert_eq!(
            bytes(&lbs, &bounded, true) - bytes(&lbs, &plain, true),
            12 * c * v + 32 * c
        );
        let previous = CrowdOptions {
            previous_positions: true,
            ..plain
        };
        assert_eq!(bytes(&lbs, &previous, true), bytes(&lbs, &plain, true));
        let tangents = CrowdOptions {
            tangents: true,
            ..plain
        };
        let extra = bytes(&rr, &tangents, true) - bytes(&rr, &plain, true);
        assert_eq!(extra, 16 * v + 32 * v + 48 * c * (p + j) + 28 * c * v);
        // Transformed normals: no positions read back, no fans, no second palette read.
        let transformed = |o: CrowdOptions| CrowdOptions {
            normals: NormalMode::Transformed,
            ..o
        };
        let fans = rr.normal_fans().entries.len() as u64;
        assert_eq!(
            bytes(&rr, &plain, true) - bytes(&rr, &transformed(plain), true),
            24 * c * v + 4 * (v + 1 + fans) - (12 * v + 12 * c * v)
        );
        assert_eq!(
            bytes(&rr, &transformed(tangents), true) - bytes(&rr, &transformed(plain), true),
            16 * v + 16 * c * v
        );
    }
}
