//! What the runtime model may cost (docs/cli.md "The cost budget"): every choice training makes
//! (how many joint-blend proxies, the kind of keys, how many delta-mush keys, the proxy
//! correctives, the pose-space correctives) is the best cross-validated one among the
//! candidates within the budget, priced by the runtime's cost model ([`rrskin::cost`]) as the
//! candidate would ship. What the budget refused is kept, with what it would have gained where
//! the cross-validation scored it, for the report.

use rrskin::cost::{Cost, Target, LAVAPIPE};
use std::sync::Mutex;

/// The default frame budget, as a multiple of the engine baseline: the engine's own skinning
/// (SSD's weights, K influences, one pass with transformed normals) and a quarter more, the
/// promise of a rig's deformation at about the cost of the skinning an engine already runs.
/// docs/cli.md gives how it was chosen.
pub const DEFAULT_FRAME: f64 = 1.25;

/// The limits a runtime model must keep (None: no limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CostBudget {
    /// The Vulkan frame with transformed normals over the engine baseline's (`--budget`).
    pub frame: Option<f64>,
    /// The CPU palette, µs a character on one core (`--palette-budget`).
    pub palette_us: Option<f64>,
}

impl Default for CostBudget {
    fn default() -> CostBudget {
        CostBudget {
            frame: Some(DEFAULT_FRAME),
            palette_us: None,
        }
    }
}

/// Whether `x` may be a limit of the budget (`--budget`, `--palette-budget`): a positive
/// number.
pub fn is_limit(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

impl CostBudget {
    /// No limit: every choice by its error alone.
    pub const NONE: CostBudget = CostBudget {
        frame: None,
        palette_us: None,
    };

    /// The largest of the price's ratios to the limits set (at most 1: within the budget; 0
    /// with no limit).
    pub fn load(&self, p: &Priced) -> f64 {
        let frame = self.frame.map_or(0.0, |limit| p.frame / limit);
        let palette = self.palette_us.map_or(0.0, |limit| p.palette_us / limit);
        frame.max(palette)
    }

    pub fn admits(&self, p: &Priced) -> bool {
        self.load(p) <= 1.0
    }
}

/// A model's predicted cost on the calibrated device ([`LAVAPIPE`]): what the budget limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Priced {
    /// The Vulkan frame with transformed normals over the engine baseline's.
    pub frame: f64,
    /// The CPU palette, µs a character on one core.
    pub palette_us: f64,
}

impl Priced {
    pub fn of(model: &rrskin::Model) -> Priced {
        Priced::from(|target| Cost::of(model, target, &LAVAPIPE))
    }

    /// The least any model of `vertices` vertices, at most `influences` influences and
    /// `delta_mush_keys` delta-mush keys is priced ([`Cost::floor`]): a count it puts over the budget
    /// is over before it is fitted.
    pub fn floor(vertices: usize, influences: usize, delta_mush_keys: usize) -> Priced {
        Priced::from(|target| Cost::floor(vertices, influences, delta_mush_keys, target, &LAVAPIPE))
    }

    fn from(cost: impl Fn(Target) -> Cost) -> Priced {
        Priced {
            frame: cost(Target::Transformed).ratio().unwrap_or(f64::INFINITY),
            palette_us: cost(Target::Palette).microseconds(),
        }
    }
}

/// A candidate the budget refused.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    /// What it was ("240 delta-mush proxies", "proxy correctives on 54 joint-blend proxies").
    pub candidate: String,
    pub priced: Priced,
    /// Its price over the budget ([`CostBudget::load`]).
    pub load: f64,
    /// Its cross-validated EE (%) and the one kept in its place, where both were scored.
    pub ee: Option<(f64, f64)>,
    /// Whether `priced` is a floor ([`Priced::floor`]): the candidate was not fitted.
    pub floor: bool,
}

impl Refused {
    /// The report's line: "240 delta-mush proxies: 1.9 EE points better, 1.8 x the budget".
    pub fn line(&self) -> String {
        let gain = match self.ee {
            Some((ee, kept)) if ee < kept => format!("{:.1} EE points better", kept - ee),
            Some((ee, kept)) => format!("{:.1} EE points worse", ee - kept),
            None if self.floor => "not fitted".to_string(),
            None => "not scored".to_string(),
        };
        let least = if self.floor { "at least " } else { "" };
        format!(
            "{}: {gain}, {least}{:.2} x the budget",
            self.candidate, self.load
        )
    }
}

/// A candidate the cross-validation scored, priced: a point of the accuracy/cost front.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// The comparison that scored it: "structure" (joint-blend P, uncorrected), "kind" (each
    /// kind with its proxy correctives) or "count" (more delta-mush proxies, corrected alike).
    pub stage: &'static str,
    /// "joint-blend", "delta-mush" or "both".
    pub kind: &'static str,
    pub proxies: usize,
    /// Its cross-validated EE (%) on the training folds, as it would ship.
    pub ee: f64,
    pub priced: Priced,
}

impl Point {
    /// Whether `other` is as good or better on error and both costs, and better on one.
    pub fn dominated_by(&self, other: &Point) -> bool {
        let (a, b) = (&self.priced, &other.priced);
        let no_worse = other.ee <= self.ee && b.frame <= a.frame && b.palette_us <= a.palette_us;
        no_worse && (other.ee < self.ee || b.frame < a.frame || b.palette_us < a.palette_us)
    }

    /// Whether no point of `points` dominates this one: it is on their front.
    pub fn on_front(&self, points: &[Point]) -> bool {
        !points.iter().any(|q| self.dominated_by(q))
    }
}

/// The budget's refusals and the front's points, as the stages meet them.
#[derive(Debug, Default)]
pub struct Ledger {
    refused: Mutex<Vec<Refused>>,
    points: Mutex<Vec<Point>>,
}

impl Ledger {
    /// Notes `candidate`, priced `priced`, as refused by `budget` (with its and the kept
    /// candidate's cross-validated EE, where scored).
    pub fn refuse(
        &self,
        budget: &CostBudget,
        candidate: String,
        priced: Priced,
        ee: Option<(f64, f64)>,
    ) {
        self.note(Refused {
            candidate,
            load: budget.load(&priced),
            priced,
            ee,
            floor: false,
        });
    }

    /// Notes `candidate` as refused by `budget` before it was fitted: its floor
    /// ([`Priced::floor`]) is over.
    pub fn refuse_unfitted(&self, budget: &CostBudget, candidate: String, floor: Priced) {
        self.note(Refused {
            candidate,
            load: budget.load(&floor),
            priced: floor,
            ee: None,
            floor: true,
        });
    }

    fn note(&self, refused: Refused) {
        // A panic elsewhere while noting leaves the list as it was: keep it.
        let mut list = self.refused.lock().unwrap_or_else(|e| e.into_inner());
        list.push(refused);
    }

    /// Notes a scored and priced candidate.
    pub fn point(&self, point: Point) {
        let mut list = self.points.lock().unwrap_or_else(|e| e.into_inner());
        // A candidate met again (the joint-blend model beside each delta-mush count) is one.
        let same =
            |p: &Point| (p.stage, p.kind, p.proxies) == (point.stage, point.kind, point.proxies);
        if !list.iter().any(same) {
            list.push(point);
        }
    }

    /// What the budget refused, and the front's points (every candidate scored and priced,
    /// in the order met).
    pub fn into_parts(self) -> (Vec<Refused>, Vec<Point>) {
        let refused = self.refused.into_inner().unwrap_or_else(|e| e.into_inner());
        let points = self.points.into_inner().unwrap_or_else(|e| e.into_inner());
        (refused, points)
    }
}

/// EE (%) of a cross-validation score (the mean relative squared error, EE² / 100²).
pub fn ee_of_score(score: f64) -> f64 {
    100.0 * score.max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_load_is_the_tighter_limit() {
        let p = Priced {
            frame: 1.5,
            palette_us: 10.0,
        };
        let both = CostBudget {
            frame: Some(1.25),
            palette_us: Some(5.0),
        };
        assert_eq!(both.load(&p), 2.0);
        assert!(!both.admits(&p));
        let frame_only = CostBudget {
            frame: Some(1.5),
            palette_us: None,
        };
        assert!(frame_only.admits(&p));
        assert_eq!(CostBudget::NONE.load(&p), 0.0);
    }

    #[test]
    fn a_refusal_says_what_it_would_have_gained() {
        let r = Refused {
            candidate: "240 delta-mush proxies".into(),
            priced: Priced {
                frame: 2.25,
                palette_us: 80.0,
            },
            load: 1.8,
            ee: Some((13.5, 15.4)),
            floor: false,
        };
        assert_eq!(
            r.line(),
            "240 delta-mush proxies: 1.9 EE points better, 1.80 x the budget"
        );
    }
}
