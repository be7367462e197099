//! The demo report's accuracy/size trade-off: the runtime model trained as `rrskin train` makes
//! it (no full model) at several P, with its enveloping error and file bytes, drawn as an SVG
//! curve beside the baselines a user would pick instead; and beside it the accuracy/cost front
//! training scored (every candidate's cross-validated EE against its predicted frame cost,
//! docs/method.md §24) with the budget's line.

use crate::eval::{self, Report};
use crate::set::ExampleSet;
use crate::train::TrainOptions;
use plotters::prelude::*;
use std::path::Path;

/// One trained size: P as trained (joint-blend stops at 3 per moving joint), EE % and bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    pub proxies: usize,
    pub train: f64,
    pub test: Option<f64>,
    pub bytes: usize,
}

/// Fractions of the main model's P trained besides it.
const FRACTIONS_OF_P: [usize; 3] = [8, 4, 2];

/// The main model's point (from `main`, the demo's report) and the runtime model retrained at
/// P/8, P/4 and P/2, smallest first.
pub fn sweep(set: &ExampleSet, main: &Report, quiet: bool) -> crate::Result<Vec<Point>> {
    let point = |r: &Report| -> Option<Point> {
        Some(Point {
            proxies: r.reduced_proxies?,
            train: r.rr_reduced?.train,
            test: r.rr_reduced?.test,
            bytes: r.model.as_ref()?.to_bytes().len(),
        })
    };
    let mut points: Vec<Point> = point(main).into_iter().collect();
    let largest = main.reduced_proxies.unwrap_or(0);
    for p in FRACTIONS_OF_P.map(|f| largest / f) {
        if p == 0 || points.iter().any(|x| x.proxies == p) {
            continue;
        }
        let options = eval::Options {
            train: TrainOptions {
                proxies: p,
                full_model: false,
                quiet,
                ..Default::default()
            },
            // Only SSD and DQS are drawn.
            skip_baselines: true,
            ..Default::default()
        };
        points.extend(point(&eval::run(set, &options)?));
    }
    points.sort_by_key(|x| x.proxies);
    points.dedup_by_key(|x| x.proxies);
    Ok(points)
}

/// Held-out EE (training EE where the set has no test poses) against P, with SSD's and DQS's;
/// and on the right the front of `report` (`front`).
pub fn plot(path: &Path, points: &[Point], report: &Report) -> crate::Result<()> {
    let output = |problem: String| crate::Error::Output {
        path: path.to_path_buf(),
        problem,
    };
    let held_out = report.test_poses > 0;
    let ee = |train: f64, test: Option<f64>| {
        if held_out {
            test.unwrap_or(train)
        } else {
            train
        }
    };
    let curve: Vec<(f64, f64)> = points
        .iter()
        .map(|x| (x.proxies as f64, ee(x.train, x.test)))
        .collect();
    let baselines = [
        ("SSD", ee(report.ssd.train, report.ssd.test), RED),
        (
            "DQS (SSD's weights)",
            ee(report.dqs.train, report.dqs.test),
            BLUE,
        ),
    ];
    let x_max = curve.iter().map(|p| p.0).fold(1.0, f64::max) * 1.05;
    let y_max = curve
        .iter()
        .map(|p| p.1)
        .chain(baselines.iter().map(|b| b.1))
        .fold(1.0, f64::max)
        * 1.15;
    let root = SVGBackend::new(path, (1200, 400)).into_drawing_area();
    let (left, right) = root.split_horizontally(640);
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        front(&right, report)?;
        let root = left;
        let split = if held_out { "held-out" } else { "training" };
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{split} EE % against proxy bones P"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
        chart
            .configure_mesh()
            .x_desc("P (proxy bones)")
            .y_desc("EE %")
            .draw()?;
        for (label, y, color) in baselines {
            chart
                .draw_series(LineSeries::new([(0.0, y), (x_max, y)], color))?
                .label(label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], color));
        }
        chart
            .draw_series(LineSeries::new(
                curve.iter().copied(),
                BLACK.stroke_width(2),
            ))?
            .label("runtime model")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK));
        chart.draw_series(curve.iter().map(|&p| Circle::new(p, 3, BLACK.filled())))?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| output(e.to_string()))
}

/// The candidates training scored (`report.points`): cross-validated EE on the training folds
/// against the predicted frame over the engine baseline, the non-dominated joined as the front,
/// and the frame budget's line.
fn front(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    report: &Report,
) -> Result<(), Box<dyn std::error::Error>> {
    let points = &report.points;
    let mut on_front: Vec<(f64, f64)> = (points.iter())
        .filter(|p| p.on_front(points))
        .map(|p| (p.priced.frame, p.ee))
        .collect();
    on_front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let budget = report.cost_budget.frame;
    let x_max = (points.iter().map(|p| p.priced.frame))
        .chain(budget)
        .fold(1.3, f64::max)
        * 1.05;
    let y_max = points.iter().map(|p| p.ee).fold(1.0, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(
            "cross-validated EE % against the frame's cost",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(1.0..x_max, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("predicted frame, x the engine baseline")
        .y_desc("EE %")
        .draw()?;
    chart.draw_series(
        (points.iter()).map(|p| Circle::new((p.priced.frame, p.ee), 3, BLACK.mix(0.35).filled())),
    )?;
    chart
        .draw_series(LineSeries::new(
            on_front.iter().copied(),
            BLACK.stroke_width(2),
        ))?
        .label("the front (every candidate: dots)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK));
    if let Some(b) = budget {
        chart
            .draw_series(LineSeries::new([(b, 0.0), (b, y_max)], RED))?
            .label(format!("budget {b} x"))
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RED));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
