//! The reduction's invariants: a runtime model written by training, loaded by the runtime and
//! evaluated by its CPU evaluator and by Vulkan (lavapipe, validation on) gives the training
//! tool's own reduced prediction; with P = T the reduced model is the full one; the vertex
//! reduction's error falls as P grows.

use glam::DVec3;
use rrskin::cpu::CpuEvaluator;
use rrskin::vk::{Batch, Context, ContextDesc, Crowd, GpuModel};
use rrskin_tools::set::{Affine, ExampleSet, Pose};
use rrskin_tools::skinning::lbs::Skinning;
use rrskin_tools::train::full_model::{self, FullModel, Prepared};
use rrskin_tools::train::reduce::c1c2::Reduced;
use rrskin_tools::train::reduce::vertex::{self, Stop};
use rrskin_tools::train::reduce::{self, Reduction};
use rrskin_tools::train::rotreg::PoseFeatures;
use rrskin_tools::train::selection::{Blend, Choice, Selection};
use rrskin_tools::train::ssd;

/// The pipeline's stages with the paper's choices (no blend, a fixed percentile and ridge).
struct Trained {
    set: ExampleSet,
    prep: Prepared,
    train: Vec<usize>,
    ssd: Skinning,
    full: FullModel,
}

const RIDGE: f64 = 1e-3;

fn train(set: ExampleSet, percentile: f64) -> Trained {
    let prep = Prepared::new(&set, PoseFeatures::all(&set));
    let train = set.train();
    let ssd = ssd::fit(
        &set,
        &train,
        &rrskin_tools::skinning::lbs::rigid_errors(&set, &train),
        4,
    );
    let selection = Selection {
        choice: Choice {
            percentile,
            ridge: RIDGE,
            blend: Blend::Regression,
        },
        alpha: vec![1.0; set.faces.len()],
    };
    let full = full_model::fit(&set, &prep, &train, &ssd, &selection).expect("factor");
    Trained {
        set,
        prep,
        train,
        ssd,
        full,
    }
}

/// The paper's reduction (§5) of the full model to `proxies` proxies with K = `influences`.
fn paper_reduction(t: &Trained, proxies: usize, influences: usize) -> Reduced {
    let reduction = Reduction {
        stop: Stop {
            proxies,
            epsilon: None,
        },
        influences,
    };
    reduce::run(&t.set, &t.prep, &t.train, &t.ssd, &t.full, &reduction)
}

fn cesiumman() -> ExampleSet {
    ExampleSet::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/cesiumman"))
        .expect("bundled data")
}

fn max_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, f64::max)
}

/// Tolerances, in units of the mesh's size (CesiumMan is ~1.5 high): the runtime stores C1, C2
/// and predictors in f32 and evaluates predictors in f32 on the GPU.
const CPU_TOLERANCE: f64 = 1e-3;
const GPU_TOLERANCE: f64 = 1e-3;

#[test]
fn the_runtime_reproduces_the_training_tools_reduced_prediction() {
    let t = train(cesiumman(), 50.0);
    let reduced = paper_reduction(&t, 30, 4);
    assert_runtime_reproduces(&t, &reduced, 30, false);
}

/// The shipped form: joint-blend proxies, their keys' stretch, their local refit, the weights
/// refitted to them.
fn joint_blend(t: &Trained, proxies: usize) -> Reduced {
    let feats = &t.prep.feats;
    let mut reduced = reduce::joint_blend::fit(&t.set, feats, &t.train, &t.ssd, proxies, 4);
    let stretch = reduce::stretch::fit(&t.set, feats, &t.train, 4, &mut reduced);
    assert!(
        stretch.ridge.is_some(),
        "the keys stayed rigid: {stretch:?}"
    );
    let refit = reduce::refit::refit(&t.set, feats, &t.train, 4, &mut reduced);
    assert!(refit.ridge.is_some(), "the refit kept C0: {refit:?}");
    reduce::joint_blend::reweight(&t.set, feats, &t.train, &t.ssd, 4, &mut reduced);
    reduced
}

#[test]
fn the_runtime_reproduces_the_joint_blend_model() {
    let t = train(cesiumman(), 50.0);
    assert_runtime_reproduces(&t, &joint_blend(&t, 30), 30, true);
}

/// The refit corrects relative motion only: when every bone moves by one rigid motion, the
/// refitted model moves the rest mesh by exactly that motion (the pose a walk's stiff spine,
/// a global turn or the rest pose is).
#[test]
fn the_refit_joint_blend_model_follows_a_rigid_motion_exactly() {
    let t = train(cesiumman(), 50.0);
    let reduced = joint_blend(&t, 30);
    let plain = reduce::joint_blend::fit(&t.set, &t.prep.feats, &t.train, &t.ssd, 30, 4);
    assert!(
        reduced.c1 != plain.c1 && reduced.c2 != plain.c2,
        "the refit changed nothing"
    );
    let motion = Affine {
        q: glam::DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 1.2),
        d: DVec3::new(0.3, -1.0, 2.0),
    };
    let mut set = t.set.clone();
    set.poses = vec![Pose {
        bones: vec![motion; set.bone_count()],
        vertices: set.rest.iter().map(|&x| motion.apply(x)).collect(),
    }];
    set.is_test = vec![true];
    let feats = PoseFeatures::all(&set);
    let moved = reduced.predict(&set, &feats[0], &set.poses[0].bones);
    let d = max_distance(&moved, &set.poses[0].vertices);
    assert!(d < 1e-9, "the refit model leaves a rigid motion by {d}");
}

/// The runtime model written from `reduced` and loaded back gives, on the CPU evaluator and on
/// Vulkan (validation on), the training tool's own prediction on the test poses; the GPU model
/// multiplies C1|C2 block-sparse (joint-blend proxies) or dense (the paper's) as `sparse` says.
fn assert_runtime_reproduces(t: &Trained, reduced: &Reduced, proxies: usize, sparse: bool) {
    let written = reduced
        .to_runtime(&t.set, 4)
        .expect("a valid runtime model")
        .to_bytes();
    let model = rrskin::Model::from_bytes(&written).expect("loads");
    assert_eq!(model.proxy_count(), proxies);

    let poses = t.set.test();
    let bones: Vec<rrskin::predict::Affine> = poses
        .iter()
        .flat_map(|&i| t.set.poses[i].bones.iter().map(Affine::to_runtime))
        .collect();
    let v = t.set.vertex_count();
    let (mut cpu, mut normals) = (
        vec![[0.0f32; 3]; poses.len() * v],
        vec![[0.0f32; 3]; poses.len() * v],
    );
    CpuEvaluator::new(&model)
        .evaluate(&bones, &mut cpu, &mut normals)
        .expect("CPU evaluation");
    let as_dvec = |p: &[[f32; 3]]| {
        p.iter()
            .map(|x| DVec3::from(x.map(f64::from)))
            .collect::<Vec<_>>()
    };
    for (n, &i) in poses.iter().enumerate() {
        let own = reduced.predict(&t.set, &t.prep.feats[i], &t.set.poses[i].bones);
        let d = max_distance(&own, &as_dvec(&cpu[n * v..(n + 1) * v]));
        assert!(
            d < CPU_TOLERANCE,
            "pose {i}: runtime CPU evaluator differs from the tool by {d}"
        );
    }

    let ctx = Context::new(&ContextDesc {
        validation: true,
        ..Default::default()
    })
    .expect("lavapipe");
    let gpu_model = GpuModel::new(&ctx, &model).expect("upload");
    assert_eq!(
        gpu_model.is_block_sparse(),
        sparse,
        "the product the model takes"
    );
    let mut crowd = Crowd::new(&gpu_model, poses.len()).expect("crowd");
    crowd.set_bones(0, &bones).expect("bones");
    Batch::new(&ctx)
        .expect("batch")
        .run(0, &[&crowd])
        .expect("run");
    let gpu = crowd.read_back().expect("read back").positions;
    let d = max_distance(&as_dvec(&gpu), &as_dvec(&cpu));
    assert!(
        d < GPU_TOLERANCE,
        "Vulkan differs from the CPU evaluator by {d}"
    );
    assert!(
        ctx.validation_messages().is_empty(),
        "{:?}",
        ctx.validation_messages()
    );
}

/// A tube on a chain of three bones bending and twisting (small enough for P = T).
fn tube() -> ExampleSet {
    let (rings, segments) = (9, 8);
    let mut rest = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            rest.push(DVec3::new(
                3.0 * r as f64 / (rings - 1) as f64,
                0.3 * a.cos(),
                0.3 * a.sin(),
            ));
        }
    }
    let mut faces = Vec::new();
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            faces.push([a, b, b + segments]);
            faces.push([a, b + segments, a + segments]);
        }
    }
    let pose = |bend: f64, twist: f64| -> Pose {
        let joint = |x: f64| {
            glam::DMat3::from_rotation_z(bend * x) * glam::DMat3::from_rotation_x(twist * x)
        };
        let bones: Vec<Affine> = (0..3)
            .map(|b| {
                let q = joint(b as f64);
                let pivot = DVec3::new(b as f64, 0.0, 0.0);
                Affine {
                    q,
                    d: pivot - q * pivot,
                }
            })
            .collect();
        // The black box: a smooth blend of the bones' motions along x.
        let vertices = rest
            .iter()
            .map(|&p| {
                let s = p.x.clamp(0.0, 2.0);
                let (b, f) = ((s.floor() as usize).min(1), s - s.floor().min(1.0));
                bones[b].apply(p) * (1.0 - f) + bones[b + 1].apply(p) * f
            })
            .collect();
        Pose { bones, vertices }
    };
    let params = [
        (0.0, 0.0),
        (0.3, 0.2),
        (-0.4, 0.5),
        (0.6, -0.3),
        (0.2, 0.7),
        (0.25, 0.35),
    ];
    let poses = params.iter().map(|&(b, t)| pose(b, t)).collect();
    ExampleSet {
        rest,
        faces,
        parents: vec![None, Some(0), Some(1)],
        poses,
        is_test: vec![false, false, false, false, false, true],
        bone_names: None,
        rig_weights: None,
        warnings: Vec::new(),
    }
}

#[test]
fn with_one_proxy_per_triangle_the_reduced_model_is_the_full_one() {
    let t = train(tube(), 25.0);
    let triangles = t.set.faces.len();
    // No reduction: every triangle its own proxy and key, every free vertex following one
    // proxy (K = 1). Blending several exact proxies (K = 8) ties on the training poses and
    // narrows what the proxies can express at the boundary (measured: 1.4e-3 on this tube).
    let reduced = paper_reduction(&t, triangles, 1);
    assert_eq!(reduced.proxies, triangles);
    let all: Vec<usize> = (0..t.set.poses.len()).collect();
    let full = t.full.predict(&t.set, &t.prep, &t.ssd, &all);
    let size = 3.0;
    for &i in &all {
        let own = reduced.predict(&t.set, &t.prep.feats[i], &t.set.poses[i].bones);
        let d = max_distance(&own, &full[i]);
        assert!(
            d < 1e-4 * size,
            "pose {i}: reduced differs from full by {d}"
        );
    }
}

#[test]
fn the_vertex_reduction_error_falls_as_proxies_grow() {
    let set = cesiumman();
    let train = set.train();
    let fixed = vec![false; set.vertex_count()];
    let mut last = f64::INFINITY;
    for p in [8, 16, 32, 64] {
        let proxies = vertex::reduce(
            &set,
            &train,
            &fixed,
            Stop {
                proxies: p,
                epsilon: None,
            },
            4,
        );
        let error: f64 = train
            .iter()
            .enumerate()
            .map(|(n, &i)| {
                (0..set.vertex_count())
                    .map(|a| {
                        let y: DVec3 = proxies.weights[a]
                            .iter()
                            .map(|&(b, w)| proxies.transforms[n][b].apply(set.rest[a]) * w)
                            .sum();
                        (y - set.poses[i].vertices[a]).length_squared()
                    })
                    .sum::<f64>()
            })
            .sum();
        assert!(error < last, "P = {p}: error {error} is not below {last}");
        last = error;
    }
}

#[test]
fn a_smaller_epsilon_stops_merging_earlier() {
    let set = cesiumman();
    let train = set.train();
    let counts: Vec<usize> = [0.02, 0.01, 0.005]
        .iter()
        .map(|&e| {
            vertex::merge_groups(
                &set,
                &train,
                Stop {
                    proxies: 1,
                    epsilon: Some(e),
                },
            )
            .1
            .len()
        })
        .collect();
    assert!(
        counts[0] < counts[1] && counts[1] < counts[2],
        "proxies for ε = 0.02, 0.01, 0.005: {counts:?}"
    );
    let capped = vertex::merge_groups(
        &set,
        &train,
        Stop {
            proxies: 40,
            epsilon: Some(0.02),
        },
    )
    .1
    .len();
    assert_eq!(capped, counts[0].max(40), "P and ε: whichever stops first");
}

/// One merging read off at several counts gives each count's own merging, and every group of
/// a finer one lies in one group of each coarser one; past ε, the coarser counts get the
/// grouping where the merging stopped.
#[test]
fn one_merging_read_off_at_several_counts_is_each_counts_merging() {
    let set = cesiumman();
    let train = set.train();
    let counts = [60, 240, 120];
    let ladder = vertex::merge_groups_at(&set, &train, &counts, None);
    for (&p, (groups, adjacency)) in counts.iter().zip(&ladder) {
        let stop = Stop {
            proxies: p,
            epsilon: None,
        };
        let (alone, _) = vertex::merge_groups(&set, &train, stop);
        assert_eq!(adjacency.len(), p);
        assert_eq!(groups, &alone, "P = {p}");
    }
    for (fine, coarse) in [(1, 2), (2, 0), (1, 0)] {
        let mut of_fine = vec![None; counts[fine]];
        for (&f, &c) in ladder[fine].0.iter().zip(&ladder[coarse].0) {
            assert_eq!(
                *of_fine[f].get_or_insert(c),
                c,
                "group {f} of {}",
                counts[fine]
            );
        }
    }
    let epsilon = Some(0.01);
    let stop = Stop {
        proxies: 1,
        epsilon,
    };
    let (at_epsilon, adjacency) = vertex::merge_groups(&set, &train, stop);
    let reached = adjacency.len();
    let stopped = vertex::merge_groups_at(&set, &train, &[reached / 2, 2 * reached], epsilon);
    assert_eq!(stopped[1].1.len(), 2 * reached);
    assert_eq!(
        stopped[0].0, at_epsilon,
        "ε stops the merging at {reached} groups"
    );
}

/// Vertex error Σ|Δ|² of `reduced` over `poses`.
fn squared_error(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> f64 {
    let feats = PoseFeatures::all(set);
    poses
        .iter()
        .map(|&i| {
            let y = reduced.predict(set, &feats[i], &set.poses[i].bones);
            y.iter()
                .zip(&set.poses[i].vertices)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum::<f64>()
        })
        .sum()
}

/// The stretch fit recovers what the runtime form can represent: examples made by joint-blend
/// keys with a known pose-driven stretch are reproduced on held-out poses from rigid keys.
#[test]
fn the_stretch_fit_recovers_a_known_stretch() {
    let mut set = rrskin_tools::cylinder_chain::Chain {
        rings: 31,
        segments: 12,
        bones: 3,
        poses: 60,
    }
    .build()
    .expect("a valid chain");
    let feats = PoseFeatures::all(&set);
    let train = set.train();
    let test: Vec<usize> = (0..set.poses.len()).filter(|&i| set.is_test[i]).collect();
    let ssd = ssd::fit(
        &set,
        &train,
        &rrskin_tools::skinning::lbs::rigid_errors(&set, &train),
        4,
    );
    let rigid = reduce::joint_blend::fit(&set, &feats, &train, &ssd, 60, 4);
    let mut truth = rigid.clone();
    for (e, key) in truth.predictors.iter_mut().enumerate() {
        // A root's rotation is the heading: the fit leaves it out (reduce::stretch).
        let bone = key.rotation.expect("a joint-blend key").first.bone;
        let joints = match set.parents[bone].and_then(|p| set.parents[p]) {
            Some(_) => 6,
            None => 3,
        };
        for o in 0..9 {
            for k in 0..joints {
                key.stretch[7 * o + k] = 0.2 * ((7 * o + 3 * k + e) as f64).sin();
            }
        }
    }
    let made: Vec<Vec<DVec3>> = (set.poses.iter().zip(&feats))
        .map(|(pose, f)| truth.predict(&set, f, &pose.bones))
        .collect();
    for (pose, vertices) in set.poses.iter_mut().zip(made) {
        pose.vertices = vertices;
    }
    let mut fitted = rigid.clone();
    let chosen = reduce::stretch::fit(&set, &feats, &train, 4, &mut fitted);
    let (before, after) = (
        squared_error(&set, &rigid, &test),
        squared_error(&set, &fitted, &test),
    );
    eprintln!("held-out Σ|Δ|²: rigid keys {before:.3e}, fitted {after:.3e} ({chosen:?})");
    assert!(after < 1e-4 * before, "rigid keys {before}, fitted {after}");
}

/// `--reduction auto` on a rig with more joint-blend candidates than P: fewer proxies (a third
/// of P here, a sixth rounding to none), P and 1.5 P are trained in the folds and scored, and
/// the model has the structure chosen.
#[test]
fn auto_scores_fewer_and_more_proxies_and_builds_the_chosen() {
    use rrskin_tools::train::{self, Method, TrainOptions};
    let set = rrskin_tools::cylinder_chain::Chain {
        rings: 21,
        segments: 8,
        bones: 3,
        poses: 40,
    }
    .build()
    .expect("a valid chain");
    let options = TrainOptions {
        proxies: 4,
        method: Method::Auto,
        full_model: false,
        quiet: true,
        ..TrainOptions::default()
    };
    let trained = train::run(&set, &options).expect("trains");
    let chosen = trained.structure.expect("a structure");
    let scored: Vec<usize> = chosen
        .candidates
        .iter()
        .map(|c| c.structure.proxies)
        .collect();
    assert_eq!(scored, [1, 4, 6], "{chosen:?}");
    assert!(
        chosen
            .candidates
            .iter()
            .all(|c| c.score > 0.0 && c.score.is_finite()),
        "{chosen:?}"
    );
    let model = trained.model.expect("a runtime model");
    assert_eq!(model.proxy_count(), chosen.structure.proxies, "{chosen:?}");
    // The model built after the choice cross-validated its own ridges.
    let grid = rrskin_tools::train::reduce::stretch::RIDGES.len();
    assert!(
        trained
            .joint_blend
            .is_some_and(|f| f.stretch.held_out.len() == grid),
        "fixed ridges in the final model"
    );
}

/// The 3-bone chain of 60 poses and its runtime model with 4 proxies, neither kind of corrective
/// (the two corrective tests add a known correction to its examples).
fn chain_with_four_proxies() -> (ExampleSet, rrskin_tools::train::Trained) {
    use rrskin_tools::train::{self, TrainOptions};
    let set = rrskin_tools::cylinder_chain::Chain {
        rings: 21,
        segments: 8,
        bones: 3,
        poses: 60,
    }
    .build()
    .expect("a valid chain");
    let options = TrainOptions {
        proxies: 4,
        full_model: false,
        correctives: 0,
        proxy_correctives: false,
        quiet: true,
        ..TrainOptions::default()
    };
    let trained = train::run(&set, &options).expect("trains");
    (set, trained)
}

/// Examples made by a runtime model plus known pose-space correctives (rest-space offsets linear
/// in one joint's vec(R − I), on the vertices that joint's bone skins): the fit finds them from
/// the training poses, and on held-out poses the model with the fitted correctives, evaluated by
/// the runtime's CPU evaluator, is far nearer the examples than the model without.
#[test]
fn the_corrective_fit_recovers_known_correctives() {
    use rrskin_tools::train::corrective;
    let (mut set, trained) = chain_with_four_proxies();
    let model = trained.model.expect("a runtime model");
    let all: Vec<usize> = (0..set.poses.len()).collect();
    let plain = corrective::Residuals::of(&set, &trained.feats, &model, &all).expect("evaluates");
    // The known corrective: driven by joint 2 (parent 1), on every vertex joint 1 or 2 skins.
    let driver = 2;
    assert_eq!(set.parents[driver], Some(1));
    let truth = |a: usize, phi: &[[f64; 9]]| -> DVec3 {
        let skinned = trained.ssd.influences[a]
            .iter()
            .any(|&(b, w)| w > 0.0 && b >= 1);
        let f = &phi[driver];
        match skinned {
            true => {
                DVec3::new(
                    0.3 * f[0] - 0.2 * f[4],
                    0.25 * f[1] + 0.1 * f[8],
                    -0.2 * f[2] + 0.15 * f[5],
                ) * (1.0 + set.rest[a].length())
            }
            false => DVec3::ZERO,
        }
    };
    for (k, &i) in all.iter().enumerate() {
        for a in 0..set.vertex_count() {
            let offset = plain.m[k][a] * truth(a, &plain.phi[k]);
            set.poses[i].vertices[a] += offset;
        }
    }
    let train = set.train();
    let test = set.test();
    let residuals =
        corrective::Residuals::of(&set, &trained.feats, &model, &train).expect("evaluates");
    let fit = corrective::fit(
        &set,
        &trained.ssd,
        &trained.rigid,
        &train,
        &residuals,
        32,
        4,
    );
    let fitted = fit.correctives.clone().expect("correctives kept");
    let with = rrskin::Model::new(rrskin::ModelParts {
        correctives: Some(fitted.to_runtime()),
        ..model.clone().into_parts()
    })
    .expect("a valid model");
    let error = |m: &rrskin::Model| -> f64 {
        let mut evaluator = CpuEvaluator::new(m);
        let v = set.vertex_count();
        let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
        test.iter()
            .map(|&i| {
                let bones: Vec<_> = set.poses[i].bones.iter().map(|b| b.to_runtime()).collect();
                evaluator
                    .evaluate(&bones, &mut pos, &mut nrm)
                    .expect("evaluates");
                (pos.iter().zip(&set.poses[i].vertices))
                    .map(|(p, y)| (DVec3::from(p.map(f64::from)) - *y).length_squared())
                    .sum::<f64>()
            })
            .sum()
    };
    let (before, after) = (error(&model), error(&with));
    eprintln!(
        "held-out Σ|Δ|²: without {before:.3e}, with {after:.3e} (ridge {:?}, N {}, D {})",
        fit.ridge,
        fitted.targets.len(),
        fitted.drivers.len()
    );
    assert!(after < 1e-2 * before, "without {before}, with {after}");
    // The error budget's pose-space ceiling is the same local model unreduced: on the held-out
    // poses it too leaves below 1 % of the error without correction.
    let held = corrective::Residuals::of(&set, &trained.feats, &model, &test).expect("evaluates");
    let offsets = corrective::ceiling(
        &set,
        &trained.ssd,
        &trained.rigid,
        &train,
        &residuals,
        4,
        &[&held],
    );
    let left = |fitted: &dyn Fn(usize, usize) -> DVec3| -> f64 {
        let mut sum = 0.0;
        for k in 0..held.delta.len() {
            for a in 0..set.vertex_count() {
                sum += (held.m[k][a] * (held.delta[k][a] - fitted(k, a))).length_squared();
            }
        }
        sum
    };
    let (plain, ceiling) = (left(&|_, _| DVec3::ZERO), left(&|k, a| offsets[0][k][a]));
    eprintln!("held-out Σ|Δ|²: without {plain:.3e}, pose-space ceiling {ceiling:.3e}");
    assert!(ceiling < 1e-2 * plain, "without {plain}, ceiling {ceiling}");
}

#[test]
fn the_proxy_corrective_fit_recovers_a_known_correction() {
    use rrskin_tools::train::{corrective, proxy_corrective, TrainOptions};
    let (mut set, trained) = chain_with_four_proxies();
    let reduced = trained.reduced.clone().expect("a reduced model");
    let drivers = proxy_corrective::drivers(&set, &trained.ssd, &reduced);
    // The known correction of proxy e, in its rest frame, from its first driver's φ: a stretch
    // along x and a shift along z, as a muscle bulging with the joint below would.
    let truth = |phi: &[[f64; 9]], palette: &mut [Affine]| {
        for (e, d) in drivers.iter().enumerate() {
            let Some(&b) = d.first() else { continue };
            let f = &phi[b];
            let (s, z) = (0.4 * f[0] - 0.3 * f[4], 0.2 * f[8] + 0.1 * f[1]);
            let t = palette[e];
            palette[e] = Affine {
                q: t.q * glam::DMat3::from_diagonal(DVec3::new(1.0 + s, 1.0, 1.0)),
                d: t.d + t.q * DVec3::new(0.0, 0.0, z),
            };
        }
    };
    for (i, f) in trained.feats.iter().enumerate() {
        let bones = set.poses[i].bones.clone();
        let mut palette = reduced.predict_proxies(&set, f, &bones);
        truth(&corrective::features(&set, f), &mut palette);
        set.poses[i].vertices = reduced.skin_with(&set, &palette, &bones);
    }
    let (train, test) = (set.train(), set.test());
    let fit = proxy_corrective::fit(
        &set,
        &trained.feats,
        &trained.ssd,
        &trained.rigid,
        &reduced,
        &train,
        &TrainOptions {
            folds: 4,
            proxy_kernels: true,
            ..TrainOptions::default()
        },
    );
    let fitted = fit.correctives.as_ref().expect("correctives kept");
    let error = |corrected: bool| -> f64 {
        test.iter()
            .map(|&i| {
                let f = &trained.feats[i];
                let mut palette = reduced.predict_proxies(&set, f, &set.poses[i].bones);
                if corrected {
                    let (phi, bones) = (corrective::features(&set, f), &set.poses[i].bones);
                    fitted.correct(&mut palette, &phi, bones);
                }
                let y = reduced.skin_with(&set, &palette, &set.poses[i].bones);
                (y.iter().zip(&set.poses[i].vertices))
                    .map(|(a, b)| (*a - *b).length_squared())
                    .sum::<f64>()
            })
            .sum()
    };
    let (before, after) = (error(false), error(true));
    eprintln!(
        "held-out Σ|Δ|²: without {before:.3e}, with {after:.3e} (chosen {:?}, {} proxies)",
        fit.chosen,
        fitted.proxies.len()
    );
    assert!(before > 1e-4, "the correction moves the mesh ({before})");
    assert!(after < 1e-2 * before, "without {before}, with {after}");
}

/// The best proxy transforms anchored to the predicted ones (the proxy correctives' targets):
/// they trade vertex fit for nearness to the anchor, monotonically in μ, and a strong anchor
/// returns the anchor itself.
#[test]
fn anchored_best_transforms_move_toward_the_anchor() {
    let (set, trained) = chain_with_four_proxies();
    let reduced = trained.reduced.clone().expect("a reduced model");
    let train = set.train();
    let anchor: Vec<Vec<Affine>> = (train.iter())
        .map(|&i| reduced.predict_proxies(&set, &trained.feats[i], &set.poses[i].bones))
        .collect();
    // (vertex error, squared distance to the anchor) summed over the training poses.
    let measure = |mu: Option<f64>| -> (f64, f64) {
        let best = reduced.best_transforms(&set, &train, mu.map(|m| (anchor.as_slice(), m)));
        let mut out = (0.0, 0.0);
        for ((&i, t), a) in train.iter().zip(&best).zip(&anchor) {
            let y = reduced.skin_with(&set, t, &set.poses[i].bones);
            out.0 += (y.iter().zip(&set.poses[i].vertices))
                .map(|(p, q)| (*p - *q).length_squared())
                .sum::<f64>();
            out.1 += (t.iter().zip(a))
                .map(|(t, a)| {
                    let m = t.q - a.q;
                    m.x_axis.length_squared()
                        + m.y_axis.length_squared()
                        + m.z_axis.length_squared()
                        + (t.d - a.d).length_squared()
                })
                .sum::<f64>();
        }
        out
    };
    let runs: Vec<(f64, f64)> = [None, Some(1e-3), Some(1e-1), Some(1e3)]
        .into_iter()
        .map(measure)
        .collect();
    eprintln!("(vertex error, distance to the anchor): {runs:?}");
    for w in runs.windows(2) {
        assert!(
            w[1].0 >= w[0].0 * (1.0 - 1e-9),
            "the fit gets no better: {runs:?}"
        );
        assert!(
            w[1].1 <= w[0].1 * (1.0 + 1e-9),
            "nearer the anchor: {runs:?}"
        );
    }
    assert!(
        runs[0].1 > 1e-6,
        "the unanchored fit moves off the prediction: {runs:?}"
    );
    assert!(
        runs[3].1 < 1e-4 * runs[0].1,
        "a strong anchor holds: {runs:?}"
    );
}
