//! Pose-space correctives (paper §8; docs/method.md §9) in the CPU reference evaluator: a zero
//! map changes nothing, a hand-computed case (one vertex, one driver) matches the formula, and
//! the weights are zero at the rest pose.

mod common;

use common::{
    affine, assert_a_zero_map_changes_nothing, cpu_reference, random_model, random_poses,
    with_correctives, Spec,
};
use rrskin::predict::corrective_weights;
use rrskin::{Correctives, Model, ModelParts};

const SPEC: Spec = Spec {
    grid: 8,
    bones: 5,
    proxies: 4,
    influences: 4,
};

#[test]
fn a_zero_map_gives_the_model_without_correctives() {
    for proxies in [0, 4] {
        let plain = random_model(Spec { proxies, ..SPEC }, 3);
        let corrected = with_correctives(&plain, 5, 9);
        let mut parts = corrected.parts().clone();
        let c = parts.correctives.as_mut().expect("correctives");
        c.map.iter_mut().for_each(|m| *m = 0.0);
        let zero = Model::new(parts).expect("valid");
        assert_eq!(zero.corrective_count(), 5);
        let bones = random_poses(&plain, 6, 2);
        let what = format!("P = {proxies}");
        assert_a_zero_map_changes_nothing(&plain, &zero, &corrected, &bones, &what);
    }
}

#[test]
fn the_weights_vanish_at_the_rest_pose() {
    let model = with_correctives(&random_model(SPEC, 4), 7, 1);
    let rest = vec![rrskin::palette::REST; model.bone_count()];
    let mut w = vec![1.0; 7];
    corrective_weights(&model, &rest, &mut w).expect("weights");
    assert_eq!(w, vec![0.0; 7]);
    let mut short = vec![0.0; 6];
    assert!(matches!(
        corrective_weights(&model, &rest, &mut short),
        Err(rrskin::Error::WrongLength { .. })
    ));
}

/// One vertex skinned to the root, a child bone driving one target: y = Q_0 (ŷ + w t) + d_0
/// with w = map · (Q_0ᵀ Q_1 − I), worked out by hand.
#[test]
fn one_vertex_and_one_driver_match_the_formula() {
    let map = [0.5f32, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0];
    let target = [0.1f32, -0.2, 0.3];
    let parts = ModelParts {
        rest_positions: vec![[1.0, 2.0, 3.0]],
        triangles: Vec::new(),
        bone_parents: vec![-1, 0],
        influences: 4,
        skin_indices: vec![0, 0, 0, 0],
        skin_weights: vec![1.0, 0.0, 0.0, 0.0],
        keys: Vec::new(),
        c1: Vec::new(),
        c2: Vec::new(),
        normal_groups: Vec::new(),
        baseline_indices: Vec::new(),
        baseline_weights: Vec::new(),
        animation: Vec::new(),
        rest_tangents: Vec::new(),
        correctives: Some(Correctives {
            drivers: vec![1],
            map: map.to_vec(),
            targets: vec![target],
        }),
        proxy_correctives: None,
    };
    let model = Model::new(parts).expect("valid");
    // Q_0: 90° about z, d_0 = (1, 0, 0); Q_1 (world): α about x.
    let alpha = 0.3f64;
    let (c, s) = (alpha.cos(), alpha.sin());
    let q0 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
    let q1 = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    let bones = [affine(q0, [1.0, 0.0, 0.0]), affine(q1, [0.0, 0.5, 0.0])];
    // R = Q_0ᵀ Q_1 has rows (0, c, −s), (−1, 0, 0), (0, s, c): φ_0 = R[0][0] − 1 = −1,
    // φ_1 = R[0][1] = c, φ_7 = R[2][1] = s.
    let w = -0.5 + c + 2.0 * s; // 0.5 φ_0 + 1 φ_1 + 2 φ_7
    let mut weights = [0.0];
    corrective_weights(&model, &bones, &mut weights).expect("weights");
    assert!((weights[0] - w).abs() < 1e-6, "{} vs {w}", weights[0]);
    let x = [1.0 + w * 0.1, 2.0 - w * 0.2, 3.0 + w * 0.3];
    // Q_0 x + d_0 = (−x_y + 1, x_x, x_z).
    let want = [1.0 - x[1], x[0], x[2]];
    let (p, n) = cpu_reference(&model, &bones);
    for i in 0..3 {
        assert!(
            (p[0][i] as f64 - want[i]).abs() < 1e-5,
            "{:?} vs {want:?}",
            p[0]
        );
    }
    assert_eq!(n[0], [0.0; 3], "no triangles, no normal");
}
