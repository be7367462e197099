//! Delta-mush proxies in the runtime model (beyond the paper; docs/method.md §23): fitted to the
//! training poses ([`crate::train::reduce::delta_mush`]), alone or after the joint-blend model's
//! proxies in one palette ([`join`]), and kept in place of the joint-blend model where the
//! k-fold cross-validation over the training poses prefers them (§18's folds, pose-relative
//! score and one-standard-error rule with its tolerance; the joint-blend structure first, then
//! the delta-mush proxies alone, then both, so that the simpler stays unless the richer wins
//! clearly).
//!
//! Direct Delta DeltaMushReport's smoothing (p, α) is chosen on all training poses, with SSD's weights
//! ([`direct_delta_mush::choose`]); the proxies' groups are merged once, on all training poses, and fixed
//! inside the folds, as the joint-blend model's ridges are there (the merging is most of the
//! cost); SSD, Ω and the weights are fitted per fold. The joint-blend side of each fold is its
//! structure as chosen. Where the runtime model takes proxy correctives, every side is compared
//! as it ships: each kind's correctives are chosen on all training poses
//! ([`proxy_corrective::fit`], which may keep none), and that choice is fitted again on each
//! fold's own poses ([`proxy_corrective::fit_candidate`]), as the merging is fixed: a kind that
//! fits the poses better uncorrected may leave less to correct.

use crate::set::ExampleSet;
use crate::skinning::direct_delta_mush::{self, DirectDeltaMush};
use crate::skinning::error::squared_error;
use crate::skinning::lbs::{rigid_errors, Skinning};
use crate::train::budget::{ee_of_score, Ledger, Point, Priced};
use crate::train::cross_validate::{try_cross_validate, Fold, Folds, Validated};
use crate::train::proxy_corrective::Candidate;
use crate::train::reduce::c1c2::Reduced;
use crate::train::reduce::delta_mush::{join, DeltaMushProxies, Groups};
use crate::train::reduce::delta_mush_keys::Keys;
use crate::train::rotreg::PoseFeatures;
use crate::train::structure::{self, Chosen, JointBlendFit, TOLERANCE};
use crate::train::{corrective, proxy_corrective};
use crate::train::{pose_scale, ssd, Method, TrainError, TrainOptions};
use glam::DVec3;
use rayon::prelude::*;

/// By how much EE a candidate with P more delta-mush keys must win on the training folds: both
/// kinds in one palette over the better kind alone, and each doubling of the delta-mush
/// proxies ([`COUNT_FACTORS`]) over the count kept, compounded. A delta-mush key is a rigid fit per
/// character, several joint-blend keys' cost (cesium_cage on lavapipe, 256 characters: paired
/// RR / SSD 1.12 → 1.44 for both kinds; the CPU palette, about 1.2 µs a key). The margin is a
/// run-time cost policy, not a fit: the joint-blend ladder asks 3 % ([`TOLERANCE`]) for 1.5
/// times the proxies.
pub const MORE_KEYS_MARGIN: f64 = 0.10;

/// The delta-mush proxy counts offered, as multiples of P (`--reduction auto`): smaller groups
/// fit a rig whose response is local (an elastic skin) better, at a rigid fit per proxy.
pub const COUNT_FACTORS: [usize; 3] = [1, 2, 4];

/// What the stage fitted and chose.
pub struct Fit {
    /// Direct Delta DeltaMushReport's Ω for SSD's weights, and its smoothing chosen on the training poses
    /// (evaluation's DDM baseline too).
    pub direct_delta_mush: DirectDeltaMush,
    pub params: direct_delta_mush::Params,
    /// The proxies' smoothing: `params`, or none (p = 0) where that fits the training poses
    /// better.
    pub proxy_params: direct_delta_mush::Params,
    /// The delta-mush proxies fitted to all training poses (K of the runtime model, and the
    /// count kept).
    pub proxies: DeltaMushProxies,
    /// (proxies, score, standard error) of each count of [`COUNT_FACTORS`] over the training
    /// folds, in the kind kept (alone or after the joint-blend proxies), each with its proxy
    /// correctives; empty where the counts were not compared (no delta-mush proxies kept, P or
    /// the kind asked for, too few triangles or poses).
    pub counts: Vec<(usize, f64, f64)>,
    pub influences: usize,
    /// (score, standard error) of the joint-blend structure, the delta-mush proxies, then
    /// both, each with its proxy correctives (where the runtime model takes them); empty with
    /// fewer training poses than folds (then the joint-blend model stays) or with
    /// [`Method::DeltaMush`] or [`Method::Both`] (then kept unasked).
    pub scores: Vec<(f64, f64)>,
    /// What the runtime model is.
    pub kept: Kept,
    /// The proxy correctives' search on the kept kind, where the cross-validation made it (the
    /// runtime model's correctives, not searched again).
    pub correctives: Option<proxy_corrective::Fit>,
}

/// The runtime model the stage keeps (asked for, or by the cross-validation); as a number, its
/// place among the cross-validation's candidates ([`Fit::scores`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kept {
    /// The joint-blend model (the structure stage's).
    JointBlend = 0,
    /// The delta-mush proxies alone ([`Fit::proxies`]).
    DeltaMush = 1,
    /// Both kinds in one palette ([`join`]).
    Both = 2,
}

impl Kept {
    /// As `rrskin eval --json` names it.
    pub fn name(self) -> &'static str {
        match self {
            Kept::JointBlend => "joint-blend",
            Kept::DeltaMush => "delta-mush",
            Kept::Both => "both",
        }
    }
}

impl Fit {
    /// P
    pub fn proxies(&self) -> usize {
        self.proxies.proxies.count()
    }

    /// The mean bones per proxy's rigid fit: the run-time cost of the keys.
    pub fn mean_bones(&self) -> f64 {
        self.proxies.proxies.mean_bones()
    }
}

/// The training poses and what the joint-blend model of the runtime was made with.
pub struct Inputs<'a> {
    pub set: &'a ExampleSet,
    pub train: &'a [usize],
    pub feats: &'a [PoseFeatures],
    pub rigid: &'a Skinning,
    pub ssd: &'a Skinning,
    pub chosen: &'a Chosen,
    pub joint_blend: &'a JointBlendFit,
    /// The joint-blend model of `chosen`, fitted to all training poses.
    pub reduced: &'a Reduced,
    /// What the cost budget refuses, noted.
    pub ledger: &'a Ledger,
}

/// Fits delta-mush proxies of K = `options.influences` to the training poses and
/// cross-validates them, alone and after the joint-blend model's, against the chosen
/// joint-blend structure (kept without asking with [`Method::DeltaMush`], alone, and
/// [`Method::Both`], after the joint-blend proxies); where they ship, as many as
/// `offered_counts` offers and the cross-validation keeps ([`MORE_KEYS_MARGIN`] a doubling).
/// With the fit, the reduced model that ships in place of the joint-blend one (None where that
/// stays), fitted to all training poses.
pub fn fit(inputs: &Inputs, options: &TrainOptions) -> Result<(Fit, Option<Reduced>), TrainError> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let mut offered = offered_counts(options, set.faces.len());
    let fewer = fewer_counts(options, offered[0]);
    let counts: Vec<usize> = offered.iter().chain(&fewer).copied().collect();
    let split = Folds::new(train.len(), options.folds);
    let compared = compares_kinds(options, split.as_ref()).is_some();
    let (chosen, joint_blend_search, mut ladder) = merge_beside(inputs, options, &counts, compared);
    let (params, vertex_direct_delta_mush) = chosen.map_err(smoothing)?;
    let mut fewer_groups = ladder.split_off(offered.len());
    let (smoothed, mut below) = match steps_down(options) {
        true => step_down(
            inputs,
            options,
            &vertex_direct_delta_mush,
            &fewer,
            &mut offered,
            &mut ladder,
            &mut fewer_groups,
        )?,
        false => (None, 0),
    };
    let (proxy_params, plain, fitted) = proxy_smoothing(
        inputs,
        k,
        params,
        &vertex_direct_delta_mush,
        &ladder[0],
        smoothed,
    )?;
    let proxy_direct_delta_mush = plain.as_ref().unwrap_or(&vertex_direct_delta_mush);
    let first = Side {
        groups: &ladder[0],
        params: &proxy_params,
        proxies: fitted,
    };
    let mut kinds = choose_kind(inputs, options, split.as_ref(), &joint_blend_search, &first)?;
    let mut proxies = first.proxies;
    // Where the budget refused the proxy correctives, fewer proxies with their correctives
    // may be the better model within it: step down while the cross-validation says so.
    for groups in &fewer_groups {
        if !kinds.correctives_refused {
            break;
        }
        let lower = Side {
            groups,
            params: &proxy_params,
            proxies: DeltaMushProxies::fit(
                set,
                train,
                proxy_direct_delta_mush,
                &inputs.ssd.influences,
                groups,
                k,
            ),
        };
        let lower_kinds =
            choose_kind(inputs, options, split.as_ref(), &joint_blend_search, &lower)?;
        if lower_kinds.kept == Kept::JointBlend || lower_kinds.score() >= kinds.score() {
            break;
        }
        (kinds, proxies, offered) = (lower_kinds, lower.proxies, vec![fewer[below]]);
        below += 1;
    }
    let larger = Ladder {
        kind: kinds.kept,
        offered: &offered,
        groups: &ladder,
        direct_delta_mush: proxy_direct_delta_mush,
        params: &proxy_params,
    };
    let counts = larger_count(
        inputs,
        options,
        split.as_ref(),
        &larger,
        &mut kinds,
        &mut proxies,
    )?;
    let out = Fit {
        direct_delta_mush: vertex_direct_delta_mush,
        params,
        proxy_params,
        proxies,
        counts,
        influences: k,
        scores: kinds.validated.map_or(Vec::new(), |v| v.scores),
        kept: kinds.kept,
        correctives: kinds.correctives,
    };
    let shipped = kinds.shipped.or_else(|| {
        let after = (out.kept == Kept::Both).then_some(inputs.reduced);
        let (ssd, feats) = (inputs.ssd, inputs.feats);
        (out.kept != Kept::JointBlend)
            .then(|| delta_mush_model(&out.proxies, (set, train), ssd, after, feats, k))
    });
    Ok((out, shipped))
}

/// Where the count steps down, the first count the budget admits ([`first_within_budget`]):
/// P, `offered` with `ladder`'s groups, or else the first of `fewer` (`fewer_groups`'), which
/// then takes their place, leaving in `fewer_groups` the smaller counts. With the proxies it
/// fitted, and how many of `fewer` it passed.
fn step_down(
    inputs: &Inputs,
    options: &TrainOptions,
    vertex_direct_delta_mush: &DirectDeltaMush,
    fewer: &[usize],
    offered: &mut Vec<usize>,
    ladder: &mut Vec<Groups>,
    fewer_groups: &mut Vec<Groups>,
) -> Result<(Option<DeltaMushProxies>, usize), TrainError> {
    let (at, fitted) = first_within_budget(
        inputs,
        options,
        vertex_direct_delta_mush,
        &ladder[0],
        fewer_groups,
    )?;
    if let Some(at) = at {
        // Fewer than P: the larger counts cost more still.
        *offered = vec![fewer[at]];
        *ladder = fewer_groups.drain(..=at).skip(at).collect();
    }
    Ok((Some(fitted), fewer.len() - fewer_groups.len()))
}

/// DDM's choice, the search of the joint-blend model's proxy correctives (where the kinds are
/// `compared`: every comparison reads it, and it needs no delta-mush proxy), and the groups
/// merged to each of `counts`. The merging runs on one thread, beside the other two, which are
/// parallel.
fn merge_beside(
    inputs: &Inputs,
    options: &TrainOptions,
    counts: &[usize],
    compared: bool,
) -> (
    crate::Result<(direct_delta_mush::Params, DirectDeltaMush)>,
    Option<proxy_corrective::Fit>,
    Vec<Groups>,
) {
    let (set, train) = (inputs.set, inputs.train);
    let ((chosen, joint_blend_search), ladder) = rayon::join(
        || {
            rayon::join(
                || direct_delta_mush::choose(set, train, &inputs.ssd.influences),
                || match compared {
                    true => corrective_search(inputs, options, inputs.reduced),
                    false => None,
                },
            )
        },
        || Groups::merge_at(set, train, counts),
    );
    (chosen, joint_blend_search, ladder)
}

/// Where the kinds' cross-validation kept a delta-mush kind and `larger` offers more counts
/// than one, the count's choice ([`choose_count`]): each count's scores, and a larger count
/// kept in place of `kinds`' proxies, correctives and model. No scores otherwise.
fn larger_count(
    inputs: &Inputs,
    options: &TrainOptions,
    split: Option<&Folds>,
    larger: &Ladder,
    kinds: &mut Kinds,
    proxies: &mut DeltaMushProxies,
) -> Result<Vec<(usize, f64, f64)>, TrainError> {
    let (Some(split), Some(validated)) = (split, &kinds.validated) else {
        return Ok(Vec::new());
    };
    if kinds.kept == Kept::JointBlend || larger.offered.len() < 2 {
        return Ok(Vec::new());
    }
    let first_row = &validated.relative[kinds.kept as usize];
    let count = choose_count(inputs, options, split, larger, first_row)?;
    if let Some(more) = count.kept {
        (*proxies, kinds.correctives, kinds.shipped) = more;
    }
    Ok(count.scores)
}

/// The delta-mush proxies of the kinds' comparison: their groups, smoothing and fit to all
/// training poses.
struct Side<'a> {
    groups: &'a Groups,
    params: &'a direct_delta_mush::Params,
    proxies: DeltaMushProxies,
}

/// What [`choose_kind`] found.
struct Kinds {
    kept: Kept,
    /// Whether the budget refused a delta-mush kind's proxy correctives.
    correctives_refused: bool,
    /// The cross-validation of the kinds, where it ran (the joint-blend model, the delta-mush
    /// proxies alone, then both where offered).
    validated: Option<Validated>,
    /// The kept kind's proxy correctives' search, where the cross-validation made it.
    correctives: Option<proxy_corrective::Fit>,
    /// The kept kind fitted to all training poses, where the cross-validation made it.
    shipped: Option<Reduced>,
}

impl Kinds {
    /// The kept kind's cross-validation score (infinite where none ran).
    fn score(&self) -> f64 {
        (self.validated.as_ref()).map_or(f64::INFINITY, |v| v.scores[self.kept as usize].0)
    }
}

/// The folds of `split` where the cross-validation compares the kinds: None where the kind is
/// asked for ([`Method::DeltaMush`], [`Method::Both`]) or there are too few poses for folds.
fn compares_kinds<'a>(options: &TrainOptions, split: Option<&'a Folds>) -> Option<&'a Folds> {
    match options.method {
        Method::DeltaMush | Method::Both => None,
        _ => split,
    }
}

/// The kind kept: asked for, or the cross-validation's over the folds of `split` (the
/// joint-blend model where there are too few poses for folds), with `joint_blend_search` the
/// search of the joint-blend model's proxy correctives ([`corrective_search`]).
fn choose_kind(
    inputs: &Inputs,
    options: &TrainOptions,
    split: Option<&Folds>,
    joint_blend_search: &Option<proxy_corrective::Fit>,
    side: &Side,
) -> Result<Kinds, TrainError> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let asked = |kept| Kinds {
        kept,
        correctives_refused: false,
        validated: None,
        correctives: None,
        shipped: None,
    };
    let split = match (options.method, compares_kinds(options, split)) {
        (_, Some(split)) => split,
        (Method::DeltaMush, None) => return Ok(asked(Kept::DeltaMush)),
        (Method::Both, None) => return Ok(asked(Kept::Both)),
        (_, None) => return Ok(asked(Kept::JointBlend)),
    };
    // Both kinds add P proxies to the joint-blend model's: where P is asked for
    // (`--reduction joint-blend`), only the delta-mush proxies alone stand against it.
    let (ssd, feats) = (inputs.ssd, inputs.feats);
    let alone = delta_mush_model(&side.proxies, (set, train), ssd, None, feats, k);
    let union = (options.method == Method::Auto).then(|| {
        let after = Some(inputs.reduced);
        delta_mush_model(&side.proxies, (set, train), ssd, after, feats, k)
    });
    let mut made: Vec<Reduced> = [alone].into_iter().chain(union).collect();
    let kinds: Vec<&Reduced> = std::iter::once(inputs.reduced).chain(&made).collect();
    let mut searched: Vec<_> = std::iter::once(joint_blend_search.clone())
        .chain(corrective_searches(inputs, options, &kinds[1..]))
        .collect();
    let had = |s: &[Option<proxy_corrective::Fit>]| -> Vec<bool> {
        (s.iter()
            .map(|f| f.as_ref().is_some_and(|f| f.correctives.is_some())))
        .collect()
    };
    let before = had(&searched);
    let priced = admit(inputs, options, &kinds, &mut searched)?;
    let correctives_refused = (before.iter().zip(had(&searched)).skip(1)).any(|(b, a)| *b && !a);
    let choices = chosen_candidates(&searched);
    let validated = cross_validate(inputs, options, split, side, &choices).map_err(smoothing)?;
    // The kinds cost more in their order: those within the budget lead.
    let index = match priced.iter().take_while(|(_, within)| *within).count() {
        n if n == kinds.len() => kept(&validated),
        1 => 0,
        n => kept(&validated.among_first(n, TOLERANCE)),
    };
    let ee = |i: usize| ee_of_score(validated.scores[i].0);
    for (i, &(priced, within)) in priced.iter().enumerate() {
        inputs.ledger.point(point("kind", kinds[i], ee(i), priced));
        if !within {
            let (what, budget) = (describe(kinds[i]), &options.budget);
            inputs
                .ledger
                .refuse(budget, what, priced, Some((ee(i), ee(index))));
        }
    }
    Ok(Kinds {
        kept: [Kept::JointBlend, Kept::DeltaMush, Kept::Both][index],
        correctives_refused,
        validated: Some(validated),
        correctives: searched.swap_remove(index),
        shipped: (index > 0).then(|| made.swap_remove(index - 1)),
    })
}

/// Prices each of `kinds` (fitted to all training poses) as it ships, with the proxy
/// correctives its search (`searched`, alike) chose, and says whether it is within the cost
/// budget. Where only the correctives put a kind over, they leave its search (noted) and it is
/// priced without them. The first kind, the joint-blend model, is always within: it is what
/// stays.
fn admit(
    inputs: &Inputs,
    options: &TrainOptions,
    kinds: &[&Reduced],
    searched: &mut [Option<proxy_corrective::Fit>],
) -> Result<Vec<(Priced, bool)>, TrainError> {
    let (set, k, budget) = (inputs.set, options.influences, &options.budget);
    let mut refused = Vec::with_capacity(kinds.len());
    for (i, (kind, search)) in kinds.iter().zip(searched.iter_mut()).enumerate() {
        let plain = kind.to_runtime(set, k)?;
        let priced = match search.as_mut() {
            Some(fit) => {
                fit.apply_within(plain, budget, inputs.ledger, &describe(kind))?
                    .1
            }
            None => Priced::of(&plain),
        };
        refused.push((priced, i == 0 || budget.admits(&priced)));
    }
    Ok(refused)
}

/// The front's point of `r` (as [`describe`] names it), scored `ee` by the comparison `stage`,
/// priced `priced`.
fn point(stage: &'static str, r: &Reduced, ee: f64, priced: Priced) -> Point {
    let delta_mush = r.delta_mush.as_ref().map_or(0, Keys::count);
    let kind = match (r.proxies - delta_mush, delta_mush) {
        (_, 0) => "joint-blend",
        (0, _) => "delta-mush",
        _ => "both",
    };
    Point {
        stage,
        kind,
        proxies: r.proxies,
        ee,
        priced,
    }
}

/// A reduced model's keys, as the report names a candidate: "54 joint-blend proxies", "60
/// delta-mush proxies", "54 joint-blend and 60 delta-mush proxies".
fn describe(r: &Reduced) -> String {
    let delta_mush = r.delta_mush.as_ref().map_or(0, Keys::count);
    match (r.proxies - delta_mush, delta_mush) {
        (jb, 0) => format!("{jb} joint-blend proxies"),
        (0, delta_mush) => format!("{delta_mush} delta-mush proxies"),
        (jb, delta_mush) => format!("{jb} joint-blend and {delta_mush} delta-mush proxies"),
    }
}

fn smoothing(e: crate::Error) -> TrainError {
    TrainError::Smoothing {
        problem: e.to_string(),
    }
}

/// The delta-mush proxy counts offered: P, and with `--reduction auto` the larger multiples of
/// [`COUNT_FACTORS`] (at most one group a triangle).
fn offered_counts(options: &TrainOptions, triangles: usize) -> Vec<usize> {
    let p = options.proxies.min(triangles);
    let mut counts = vec![p];
    if options.method == Method::Auto {
        for f in &COUNT_FACTORS[1..] {
            let c = (f * p).min(triangles);
            if c > counts[counts.len() - 1] {
                counts.push(c);
            }
        }
    }
    counts
}

/// The counts below P the cost budget may step down to: P/2, P/4, … down to 1 (none where it
/// does not step down, [`steps_down`]).
fn fewer_counts(options: &TrainOptions, p: usize) -> Vec<usize> {
    let first = steps_down(options).then_some(p / 2);
    std::iter::successors(first, |&c| Some(c / 2))
        .take_while(|&c| c >= 1)
        .collect()
}

/// Whether the cost budget may step the delta-mush count below P: it limits something, and P
/// was not asked for (`--reduction delta-mush` or `both` build the P asked).
fn steps_down(options: &TrainOptions) -> bool {
    let asked = matches!(options.method, Method::DeltaMush | Method::Both);
    !asked && options.budget != crate::train::budget::CostBudget::NONE
}

/// Where the delta-mush proxies alone at P (`groups`, smoothed by `vertex_direct_delta_mush`) are over the
/// cost budget (noted), the index in `fewer` (P/2, P/4, …) of the largest count within it
/// (the cheapest where none is; None where P is within it, or is the cheapest), with the
/// proxies of that count (the fit [`proxy_smoothing`] would make with `vertex_direct_delta_mush`). A count
/// is fitted only where neither its floor ([`Priced::floor`]) nor the last fitted count's load
/// scaled down to it puts it over: an impossible request is answered without fitting it.
fn first_within_budget(
    inputs: &Inputs,
    options: &TrainOptions,
    vertex_direct_delta_mush: &DirectDeltaMush,
    groups: &Groups,
    fewer: &[Groups],
) -> Result<(Option<usize>, DeltaMushProxies), TrainError> {
    let budget = &options.budget;
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let price = |groups: &Groups| -> Result<(Priced, DeltaMushProxies), TrainError> {
        let proxies = DeltaMushProxies::fit(
            set,
            train,
            vertex_direct_delta_mush,
            &inputs.ssd.influences,
            groups,
            k,
        );
        let model = delta_mush_model(&proxies, (set, train), inputs.ssd, None, inputs.feats, k);
        Ok((Priced::of(&model.to_runtime(set, k)?), proxies))
    };
    let counts: Vec<&Groups> = std::iter::once(groups).chain(fewer).collect();
    let (last, named) = (fewer.len(), |g: &Groups| {
        format!("{} delta-mush proxies", g.adjacency.len())
    });
    let mut fitted: Option<(usize, f64)> = None;
    for (i, g) in counts[..last].iter().enumerate() {
        let count = g.adjacency.len();
        let floor = Priced::floor(set.rest.len(), k, count);
        if !budget.admits(&floor) {
            inputs.ledger.refuse_unfitted(budget, named(g), floor);
            continue;
        }
        // The load scaled down with the count is below the count's own (the engine's part
        // does not scale): a count it puts over is over.
        if fitted.is_some_and(|(c, load)| load * count as f64 / c as f64 > 1.0) {
            continue;
        }
        let (priced, proxies) = price(g)?;
        if budget.admits(&priced) {
            return Ok((i.checked_sub(1), proxies));
        }
        inputs.ledger.refuse(budget, named(g), priced, None);
        fitted = Some((count, budget.load(&priced)));
    }
    // The cheapest count ships even over the budget, noted.
    let (priced, proxies) = price(counts[last])?;
    if !budget.admits(&priced) {
        inputs
            .ledger
            .refuse(budget, named(counts[last]), priced, None);
    }
    Ok((last.checked_sub(1), proxies))
}

/// The proxies' smoothing on `groups`: DDM's `params` (Ω `vertex_direct_delta_mush`), or none (p = 0: each
/// group's rigid fit of its LBS motion), whichever fits the training poses better (the same
/// models, so no cross-validation). The smoothing kept, its Ω where it is none (else
/// `vertex_direct_delta_mush`'s), and the proxies fitted with it. `smoothed`: the proxies of `groups` with
/// `vertex_direct_delta_mush` where the budget's count search fitted them already.
fn proxy_smoothing(
    inputs: &Inputs,
    k: usize,
    params: direct_delta_mush::Params,
    vertex_direct_delta_mush: &DirectDeltaMush,
    groups: &Groups,
    smoothed: Option<DeltaMushProxies>,
) -> Result<
    (
        direct_delta_mush::Params,
        Option<DirectDeltaMush>,
        DeltaMushProxies,
    ),
    TrainError,
> {
    let (set, train, ssd_weights) = (inputs.set, inputs.train, &inputs.ssd.influences);
    let unsmoothed = direct_delta_mush::Params {
        iterations: 0,
        ..params
    };
    let bones = set.bone_count();
    let plain = DirectDeltaMush::new(&set.rest, &set.faces, ssd_weights, bones, &unsmoothed)
        .map_err(smoothing)?;
    let fit = |d: &DirectDeltaMush| DeltaMushProxies::fit(set, train, d, ssd_weights, groups, k);
    let scored = |m: DeltaMushProxies| {
        let meshes: Vec<Vec<DVec3>> = (train.iter())
            .map(|&i| m.deform(&set.rest, &set.poses[i].bones))
            .collect();
        (squared_error(set, train, &meshes), m)
    };
    let smoothed = smoothed.unwrap_or_else(|| fit(vertex_direct_delta_mush));
    let ((smoothed_error, smoothed), (plain_error, unsmoothed_fit)) =
        (scored(smoothed), scored(fit(&plain)));
    Ok(match plain_error < smoothed_error {
        true => (unsmoothed, Some(plain), unsmoothed_fit),
        false => (params, None, smoothed),
    })
}

/// The delta-mush proxy counts offered (P first), their groupings, and the proxies' Ω and
/// smoothing, for the kind kept (the proxies alone, or after the joint-blend model's).
struct Ladder<'a> {
    kind: Kept,
    offered: &'a [usize],
    groups: &'a [Groups],
    direct_delta_mush: &'a DirectDeltaMush,
    params: &'a direct_delta_mush::Params,
}

/// The delta-mush `proxies`' model as it ships, fitted to `poses` of a set with SSD `ssd`:
/// after `joint_blend`'s proxies (both kinds in one palette), or alone.
fn delta_mush_model(
    proxies: &DeltaMushProxies,
    (set, poses): (&ExampleSet, &[usize]),
    ssd: &Skinning,
    joint_blend: Option<&Reduced>,
    feats: &[PoseFeatures],
    k: usize,
) -> Reduced {
    match joint_blend {
        Some(jb) => join(jb, proxies, set, poses, feats, k),
        None => proxies.reduced(set.bone_count(), &ssd.influences),
    }
}

/// What [`choose_count`] found.
struct Count {
    /// (proxies, score, standard error) of each count offered.
    scores: Vec<(usize, f64, f64)>,
    /// A larger count kept: its proxies, their correctives' search and the reduced model.
    kept: Option<(
        DeltaMushProxies,
        Option<proxy_corrective::Fit>,
        Option<Reduced>,
    )>,
}

/// Cross-validates the delta-mush proxies of each larger count of `ladder` as they ship, each
/// with the proxy correctives its own search keeps on all training poses (refitted per fold),
/// against P's, whose held-out relative errors over the same folds are `first` (the kinds'
/// cross-validation's), and keeps a larger count where [`kept_count`] says.
fn choose_count(
    inputs: &Inputs,
    options: &TrainOptions,
    split: &Folds,
    ladder: &Ladder,
    first: &[f64],
) -> Result<Count, TrainError> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let (ssd_weights, bones) = (&inputs.ssd.influences, set.bone_count());
    let larger = &ladder.groups[1..];
    let after = (ladder.kind == Kept::Both).then_some(inputs.reduced);
    let mut fitted: Vec<(DeltaMushProxies, Reduced)> = (larger.iter())
        .map(|groups| {
            let proxies =
                DeltaMushProxies::fit(set, train, ladder.direct_delta_mush, ssd_weights, groups, k);
            let reduced =
                delta_mush_model(&proxies, (set, train), inputs.ssd, after, inputs.feats, k);
            (proxies, reduced)
        })
        .collect();
    let within = counts_within_budget(inputs, options, &fitted)?;
    fitted.truncate(within);
    if within == 0 {
        let (score, se) = Validated::of(vec![first.to_vec()], TOLERANCE).scores[0];
        return Ok(Count {
            scores: vec![(ladder.offered[0], score, se)],
            kept: None,
        });
    }
    let larger = &larger[..within];
    let models: Vec<&Reduced> = fitted.iter().map(|(_, reduced)| reduced).collect();
    let mut searched = corrective_searches(inputs, options, &models);
    let shipped = admit(inputs, options, &models, &mut searched)?;
    let choices = chosen_candidates(&searched);
    let normaliser = pose_scale::rigid_pose_errors(set, train, inputs.rigid);
    let held_out = try_cross_validate(split, &normaliser, larger.len(), TOLERANCE, |fold| {
        let f = FoldFit::new(inputs, k, fold);
        let fold_direct_delta_mush = DirectDeltaMush::new(
            &set.rest,
            &set.faces,
            &f.ssd.influences,
            bones,
            ladder.params,
        )?;
        let joint_blend =
            (ladder.kind == Kept::Both).then(|| fold_joint_blend(inputs, options, &f));
        Ok::<_, crate::Error>(
            (larger.iter().zip(&choices))
                .map(|(groups, choice)| {
                    let influences = &f.ssd.influences;
                    let delta_mush = DeltaMushProxies::fit(
                        &f.set,
                        &f.inner,
                        &fold_direct_delta_mush,
                        influences,
                        groups,
                        k,
                    );
                    let model = delta_mush_model(
                        &delta_mush,
                        (&f.set, &f.inner),
                        &f.ssd,
                        joint_blend.as_ref(),
                        inputs.feats,
                        k,
                    );
                    f.held_errors(inputs, options, &model, choice)
                })
                .collect(),
        )
    })
    .map_err(smoothing)?;
    let rows = std::iter::once(first.to_vec()).chain(held_out.relative);
    let scores: Vec<(usize, f64, f64)> = (ladder.offered[..=within].iter())
        .zip(Validated::of(rows.collect(), TOLERANCE).scores)
        .map(|(&p, (score, se))| (p, score, se))
        .collect();
    for ((_, reduced), (&(_, score, _), &(priced, _))) in
        fitted.iter().zip(scores[1..].iter().zip(&shipped))
    {
        inputs
            .ledger
            .point(point("count", reduced, ee_of_score(score), priced));
    }
    let index = kept_count(&scores);
    Ok(Count {
        scores,
        kept: (index > 0).then(|| {
            let (proxies, reduced) = fitted.swap_remove(index - 1);
            (proxies, searched.swap_remove(index - 1), Some(reduced))
        }),
    })
}

/// How many of the larger counts' models (`fitted`, uncorrected, each costlier than the one
/// before) are within the cost budget: those that lead; the others are noted as refused, not
/// scored.
fn counts_within_budget(
    inputs: &Inputs,
    options: &TrainOptions,
    fitted: &[(DeltaMushProxies, Reduced)],
) -> Result<usize, TrainError> {
    let (budget, k) = (&options.budget, options.influences);
    let mut within = fitted.len();
    for (i, (_, reduced)) in fitted.iter().enumerate() {
        let priced = Priced::of(&reduced.to_runtime(inputs.set, k)?);
        if within == fitted.len() && !budget.admits(&priced) {
            within = i;
        }
        if i >= within {
            inputs
                .ledger
                .refuse(budget, describe(reduced), priced, None);
        }
    }
    Ok(within)
}

/// The count kept of `counts` ((proxies, score, standard error), smallest first): each larger
/// count where it beats the count kept so far by [`MORE_KEYS_MARGIN`] a doubling (4P against P
/// by 21 % EE: the keys' cost grows with their count).
fn kept_count(counts: &[(usize, f64, f64)]) -> usize {
    let clear = |&(more, score, _): &(usize, f64, f64),
                 &(kept, kept_score, _): &(usize, f64, f64)| {
        wins_by_margin(score, kept_score, (more as f64 / kept as f64).log2())
    };
    (1..counts.len()).fold(0, |kept, i| match clear(&counts[i], &counts[kept]) {
        true => i,
        false => kept,
    })
}

/// A fold's side of a cross-validation: its inner poses' set and SSD, and its held-out poses
/// with their correctives' features (once, for every model the fold scores).
struct FoldFit {
    /// The fold's index in the split.
    fold: usize,
    set: ExampleSet,
    inner: Vec<usize>,
    ssd: Skinning,
    held: Vec<usize>,
    phi: Vec<Vec<[f64; 9]>>,
}

impl FoldFit {
    fn new(inputs: &Inputs, k: usize, fold: &Fold) -> FoldFit {
        let (_, held) = fold.poses(inputs.train);
        let set = inputs.set.holding_out(&held);
        let inner = set.train();
        // The structure's folds are these folds (the same split and K): their SSD.
        let ssd = match inputs.chosen.built.ssd(fold.index) {
            Some(ssd) => ssd.clone(),
            None => ssd::fit(&set, &inner, &rigid_errors(&set, &inner), k),
        };
        let phi = (held.iter())
            .map(|&i| corrective::features(inputs.set, &inputs.feats[i]))
            .collect();
        FoldFit {
            fold: fold.index,
            set,
            inner,
            ssd,
            held,
            phi,
        }
    }

    /// The squared errors of the held-out poses of `model` (fitted on the inner poses),
    /// corrected as `candidate` says (refitted on the inner poses).
    fn held_errors(
        &self,
        inputs: &Inputs,
        options: &TrainOptions,
        model: &Reduced,
        candidate: &Option<Candidate>,
    ) -> Vec<f64> {
        let (set, feats) = (inputs.set, inputs.feats);
        let correctives = candidate.and_then(|c| {
            let (inner_set, inner) = (&self.set, &self.inner);
            proxy_corrective::fit_candidate(
                inner_set, feats, &self.ssd, model, inner, &c, options.up,
            )
        });
        (self.held.iter().zip(&self.phi))
            .map(|(&i, phi)| {
                let (f, pose_bones) = (&feats[i], &set.poses[i].bones);
                let mut palette = model.predict_proxies(set, f, pose_bones);
                if let Some(c) = &correctives {
                    c.correct(&mut palette, phi, pose_bones);
                }
                let mesh = model.skin_with(set, &palette, pose_bones);
                squared_error(set, &[i], &[mesh])
            })
            .collect()
    }
}

/// Per kind of `kinds` (fitted to all training poses), the search of its proxy correctives
/// (None where the runtime model takes none).
fn corrective_searches(
    inputs: &Inputs,
    options: &TrainOptions,
    kinds: &[&Reduced],
) -> Vec<Option<proxy_corrective::Fit>> {
    // The kinds in parallel, not only each search's folds: a search has serial parts, and
    // three of them one after the other left a core idle (3.7 s against 1.4 s on human_heavy).
    (kinds.par_iter())
        .map(|model| corrective_search(inputs, options, model))
        .collect()
}

/// The search of `model`'s proxy correctives (fitted to all training poses; None where the
/// runtime model takes none).
fn corrective_search(
    inputs: &Inputs,
    options: &TrainOptions,
    model: &Reduced,
) -> Option<proxy_corrective::Fit> {
    let (set, train, feats) = (inputs.set, inputs.train, inputs.feats);
    let (ssd, rigid) = (inputs.ssd, inputs.rigid);
    (options.proxy_correctives)
        .then(|| proxy_corrective::fit(set, feats, ssd, rigid, model, train, options))
}

/// Each search's chosen candidate (None: uncorrected, or no search).
fn chosen_candidates(searched: &[Option<proxy_corrective::Fit>]) -> Vec<Option<Candidate>> {
    (searched.iter())
        .map(|fit| fit.as_ref().and_then(|f| f.chosen))
        .collect()
}

/// The candidates' scores over the folds of `split`: the chosen joint-blend structure, the
/// delta-mush proxies of `side`'s groups and smoothing, and, where offered (a third corrective
/// choice), both in one palette; each corrected as `correctives` say.
fn cross_validate(
    inputs: &Inputs,
    options: &TrainOptions,
    split: &Folds,
    side: &Side,
    correctives: &[Option<Candidate>],
) -> crate::Result<Validated> {
    let (set, train, k) = (inputs.set, inputs.train, options.influences);
    let normaliser = pose_scale::rigid_pose_errors(set, train, inputs.rigid);
    try_cross_validate(split, &normaliser, correctives.len(), TOLERANCE, |fold| {
        let f = FoldFit::new(inputs, k, fold);
        let reduced = fold_joint_blend(inputs, options, &f);
        let bones = set.bone_count();
        let influences = &f.ssd.influences;
        let fold_direct_delta_mush =
            DirectDeltaMush::new(&set.rest, &set.faces, influences, bones, side.params)?;
        let delta_mush = DeltaMushProxies::fit(
            &f.set,
            &f.inner,
            &fold_direct_delta_mush,
            influences,
            side.groups,
            k,
        );
        // Each kind's held-out errors, as it ships: corrected as its candidate says.
        let held_error =
            |model: &Reduced, candidate| f.held_errors(inputs, options, model, candidate);
        let (poses, feats) = ((&f.set, &f.inner[..]), inputs.feats);
        let shipped = |after| delta_mush_model(&delta_mush, poses, &f.ssd, after, feats, k);
        let c = correctives;
        let mut rows = vec![
            held_error(&reduced, &c[0]),
            held_error(&shipped(None), &c[1]),
        ];
        if let Some(both) = c.get(2) {
            rows.push(held_error(&shipped(Some(&reduced)), both));
        }
        Ok(rows)
    })
}

/// The chosen joint-blend structure fitted to a fold's inner poses, with the ridges chosen on
/// all training poses.
fn fold_joint_blend(inputs: &Inputs, options: &TrainOptions, f: &FoldFit) -> Reduced {
    let (structure, ridges) = (&inputs.chosen.structure, inputs.joint_blend.ridges());
    // The structure's cross-validation built it on this fold already, where its ridges were
    // these.
    if let Some(built) = inputs.chosen.built.model(f.fold, structure, ridges) {
        return built.clone();
    }
    let (feats, ridges) = (inputs.feats, Some(ridges));
    structure::build(&f.set, feats, &f.ssd, None, structure, options, ridges).0
}

/// The candidate kept: the rule's, but both kinds only where they beat the better kind alone
/// by [`MORE_KEYS_MARGIN`] (else the rule again over the two alone).
fn kept(validated: &Validated) -> usize {
    let alone = &validated.scores[..2];
    let best_alone = alone.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
    // Both kinds add P keys to the better kind's: one doubling's margin.
    let clear = |both: f64| wins_by_margin(both, best_alone, 1.0);
    match validated.chosen {
        2 if !clear(validated.scores[2].0) => validated.among_first(2, TOLERANCE).chosen,
        chosen => chosen,
    }
}

/// Whether a candidate of `score` with more delta-mush keys beats `against` by
/// [`MORE_KEYS_MARGIN`] EE for each of its `doublings` of the keys, compounded (scores are EE²).
fn wins_by_margin(score: f64, against: f64, doublings: f64) -> bool {
    score * (1.0 + MORE_KEYS_MARGIN).powf(2.0 * doublings) <= against
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (proxies, score) as EE % (the score is EE² / 100²).
    fn counts(ee: &[(usize, f64)]) -> Vec<(usize, f64, f64)> {
        ee.iter()
            .map(|&(p, e)| (p, (e / 100.0).powi(2), 0.0))
            .collect()
    }

    #[test]
    fn each_doubling_of_the_count_must_win_by_the_margin() {
        // 2P by 12 %, then 4P by 12 % over 2P.
        assert_eq!(
            kept_count(&counts(&[(60, 12.4), (120, 11.0), (240, 9.8)])),
            2
        );
        // 2P by 12 %, 4P by 3 % over it.
        assert_eq!(
            kept_count(&counts(&[(60, 18.9), (120, 16.7), (240, 16.2)])),
            1
        );
        // 2P by 8 %, 4P by 14 % over P: short of two doublings' 21 %.
        assert_eq!(
            kept_count(&counts(&[(60, 12.6), (120, 11.7), (240, 11.1)])),
            0
        );
        // 2P by 9 %, 4P by 29 % over P.
        assert_eq!(
            kept_count(&counts(&[(60, 10.0), (120, 9.1), (240, 7.75)])),
            2
        );
        // Capped at one group a triangle: 3 to 5 is less than a doubling, and asks less.
        assert_eq!(kept_count(&counts(&[(3, 10.0), (5, 9.2)])), 1);
        assert_eq!(kept_count(&counts(&[(3, 10.0), (6, 9.2)])), 0);
    }
}
