//! The demo's report page (report.html, beside the images): the error table, the images with
//! their captions, and the colour scale with its unit.

use crate::eval::Errors;
use crate::run::demo::Outputs;
use std::fmt::Write;
use std::path::Path;

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

fn file_name(path: &Path) -> String {
    escape(
        &path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
    )
}

pub fn write(path: &Path, o: &Outputs) -> crate::Result<()> {
    let r = &o.report;
    let mut rows = vec![
        ("rigid", Some(r.rigid)),
        ("SSD (LBS, fitted weights)", Some(r.ssd)),
        ("DQS (SSD's weights)", Some(r.dqs)),
        ("LBS (the rig's weights)", r.rig_lbs),
        ("DQS (the rig's weights)", r.rig_dqs),
        ("rotational regression, full model", r.rr_full),
    ];
    let reduced = format!(
        "<b>runtime model</b> (P = {})",
        r.reduced_proxies.unwrap_or(0)
    );
    rows.push((&reduced, r.rr_reduced));
    let pct = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{x:.1}"));
    let mut table = String::new();
    for (label, e) in rows {
        if let Some(Errors { train, test }) = e {
            let _ = writeln!(
                table,
                "<tr><td>{label}</td><td>{}</td><td>{}</td></tr>",
                pct(Some(train)),
                pct(test)
            );
        }
    }
    let mut sizes = String::new();
    for x in &o.tradeoff {
        let _ = writeln!(
            sizes,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            x.proxies,
            x.bytes,
            pct(Some(x.train)),
            pct(x.test)
        );
    }
    let set = escape(&o.set);
    let html = format!(
        r#"<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>rrskin demo: {set}</title>
<style>body{{font-family:sans-serif;max-width:1240px;margin:2em auto}} td,th{{padding:2px 12px;text-align:right}} td:first-child,th:first-child{{text-align:left}}
.scale{{display:inline-block;width:320px;height:14px;vertical-align:middle;background:linear-gradient(to right,rgb(51,89,230),rgb(51,204,153),rgb(242,204,26),rgb(242,38,26))}}</style></head>
<body><h1>rrskin demo: {set}</h1>
<p>{v} vertices, {t} triangles, {j} bones; {ntrain} training poses, {ntest} held-out test poses; rendered with the Vulkan runtime on {device}.</p>
<h2>Enveloping error (EE %, 100 = the best rigid predictor)</h2>
<table><tr><th>method</th><th>train</th><th>test</th></tr>
{table}</table>
<h2>Accuracy against size: the runtime model at several P</h2>
<table><tr><th>P</th><th>model bytes</th><th>train EE %</th><th>test EE %</th></tr>
{sizes}</table>
<figure><img src="{tradeoff}" width="640"><figcaption>EE % of the runtime model against P, with SSD's and DQS's (trained as <code>rrskin train --proxies P</code>)</figcaption></figure>
<h2>The held-out pose where SSD errs most (pose {pose})</h2>
<p>Per-vertex error: <span>0</span> <span class="scale"></span> <span>&ge; {scale:.4} mesh units (2 % of the height)</span>.
RMS vertex error: SSD {rms_ssd:.4}, runtime model {rms_rr:.4} mesh units.</p>
<figure><img src="{comparison}" width="1200"><figcaption>ground truth | SSD | runtime model, one camera for all three</figcaption></figure>
<figure><img src="{closeup}" width="800"><figcaption>SSD | runtime model, close-up where the runtime model gains most on SSD</figcaption></figure>
<figure><img src="{crowd}" width="1200"><figcaption>{crowd_count} characters of the runtime model, one command buffer</figcaption></figure>
</body></html>
"#,
        v = r.vertices,
        t = r.triangles,
        j = r.bones,
        ntrain = r.train_poses,
        ntest = r.test_poses,
        device = escape(&o.device),
        pose = o.pose,
        scale = o.scale,
        rms_ssd = o.rms.0,
        rms_rr = o.rms.1,
        comparison = file_name(&o.comparison),
        closeup = file_name(&o.closeup),
        tradeoff = file_name(&o.tradeoff_plot),
        crowd = file_name(&o.crowd),
        crowd_count = crate::run::demo::CROWD,
    );
    std::fs::write(path, html).map_err(|e| crate::Error::Output {
        path: path.to_path_buf(),
        problem: format!("cannot write: {e}"),
    })
}
