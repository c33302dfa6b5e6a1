//! The SVG figures of a run: accuracy vs noise level, novelty ROC curves, and the
//! labelled-map panels (ground truth, wrong evidence, each model's labels; placeholder
//! marginals as pies).

use std::fmt::Write as _;

use super::evidence::NoiseLevel;
use super::models::{FIRST_PAPER_MODEL, GRAPHSPN, MODELS, MRF2, NUM_MODELS, TREES};
use super::novelty::{NoveltySet, novelty_points, roc_curve};
use super::reproduce::{BuildingSetup, GraphOutcome};
use super::results::{Experiment, Reproduction, set_score};
use super::stats::levels_of;
use super::summary::{Interval, SummaryCell, cell};
use crate::map::TopoMap;
use crate::render::{RenderOptions, escape_xml, render_svg};
use crate::template::Template;

const MODEL_COLOURS: [&str; NUM_MODELS] = [
    "#9467bd", "#d62728", "#1f77b4", "#2ca02c", "#ff9896", "#9ecae1", "#a1d99b",
];

/// An SVG line chart frame: returns (svg prefix, x→px, y→px) for data in `[x0, x1] × [0, 1]`.
struct Frame {
    w: f64,
    h: f64,
    left: f64,
    top: f64,
    pw: f64,
    ph: f64,
    x0: f64,
    x1: f64,
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x0) / (self.x1 - self.x0) * self.pw
    }
    fn py(&self, y: f64) -> f64 {
        self.top + (1.0 - y) * self.ph
    }
    fn start(&self, title: &str, xlabel: &str, ylabel: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#,
            w = self.w,
            h = self.h
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="20" font-size="15" text-anchor="middle">{}</text>"#,
            self.w / 2.0,
            escape_xml(title)
        );
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333"/>"##,
            self.left, self.top, self.pw, self.ph
        );
        for k in 0..=10 {
            let y = k as f64 / 10.0;
            let _ = writeln!(
                s,
                r##"<line x1="{l}" x2="{r}" y1="{y}" y2="{y}" stroke="#ddd"/><text x="{tx}" y="{ty}" text-anchor="end">{lab}</text>"##,
                l = self.left,
                r = self.left + self.pw,
                y = self.py(y),
                tx = self.left - 5.0,
                ty = self.py(y) + 4.0,
                lab = if self.x1 > 1.5 {
                    format!("{}", k * 10)
                } else {
                    format!("{y:.1}")
                }
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            self.left + self.pw / 2.0,
            self.h - 8.0,
            escape_xml(xlabel)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate(14,{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            self.top + self.ph / 2.0,
            escape_xml(ylabel)
        );
        s
    }
}

fn polyline(pts: &[(f64, f64)], colour: &str, dash: bool) -> String {
    let p: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
    format!(
        r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"{}/>"#,
        p.join(" "),
        if dash {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        }
    ) + "\n"
}

fn legend(s: &mut String, x: f64, y: f64, items: &[(&str, &str)]) {
    for (i, (name, col)) in items.iter().enumerate() {
        let yy = y + 16.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{x}" x2="{}" y1="{yy}" y2="{yy}" stroke="{col}" stroke-width="3"/><text x="{}" y="{}">{}</text>"#,
            x + 20.0,
            x + 25.0,
            yy + 4.0,
            escape_xml(name)
        );
    }
}

/// Accuracy (%) vs noise level for one building: one line per model, bars = map-level
/// bootstrap 95% intervals (the cells of [`summarise`](super::summary::summarise)).
pub fn accuracy_plot(rep: &Reproduction, cells: &[SummaryCell], building: &str) -> String {
    let levels = levels_of(rep);
    let (lo, hi) = (
        *levels.first().unwrap_or(&1) as f64,
        *levels.last().unwrap_or(&6) as f64,
    );
    let fr = Frame {
        w: 520.0,
        h: 360.0,
        left: 55.0,
        top: 35.0,
        pw: 330.0,
        ph: 280.0,
        x0: lo - 0.3,
        x1: hi + 0.3,
    };
    let mut s = fr.start(
        &format!("Classification accuracy, test building {building}"),
        "noise level",
        "accuracy (%)",
    );
    for &l in &levels {
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">NL{l}</text>"#,
            fr.px(l as f64),
            fr.top + fr.ph + 16.0
        );
    }
    let mut items = Vec::new();
    let mut all_models: Vec<Option<usize>> = (0..NUM_MODELS).map(Some).collect();
    all_models.push(None);
    for (k, model) in all_models.into_iter().enumerate() {
        let (col, name, dash) = match model {
            Some(m) => (MODEL_COLOURS[m], MODELS[m], m >= FIRST_PAPER_MODEL),
            None => ("#888888", "evidence only", true),
        };
        let mut pts = Vec::new();
        for &l in &levels {
            let c = cell(cells, Some(building), Experiment::Classification, l);
            if let Some(Interval {
                mean: m,
                low: lo,
                high: hi,
            }) = model.map_or(c.evidence_only, |m| c.accuracy[m])
            {
                let x = fr.px(l as f64) + (k as f64 - 3.0) * 3.0;
                pts.push((x, fr.py(m)));
                let _ = writeln!(
                    s,
                    r#"<line x1="{x:.1}" x2="{x:.1}" y1="{:.1}" y2="{:.1}" stroke="{col}"/>"#,
                    fr.py(lo),
                    fr.py(hi)
                );
            }
        }
        s.push_str(&polyline(&pts, col, dash));
        items.push((name, col));
    }
    legend(&mut s, fr.left + fr.pw + 15.0, fr.top + 20.0, &items);
    s.push_str("</svg>\n");
    s
}

/// ROC curves of one novelty set, one per model, with AUC in the legend.
pub fn roc_plot(rep: &Reproduction, set: NoveltySet) -> String {
    let fr = Frame {
        w: 520.0,
        h: 380.0,
        left: 55.0,
        top: 35.0,
        pw: 300.0,
        ph: 300.0,
        x0: 0.0,
        x1: 1.0,
    };
    let mut s = fr.start(
        match set {
            NoveltySet::Paper => "Novelty detection ROC (paper's swaps)",
            NoveltySet::Local => "Novelty detection ROC (local swaps)",
        },
        "false-positive rate",
        "true-positive rate",
    );
    for k in 0..=10 {
        let x = k as f64 / 10.0;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{x:.1}</text>"#,
            fr.px(x),
            fr.top + fr.ph + 16.0
        );
    }
    s.push_str(&polyline(
        &[(fr.px(0.0), fr.py(0.0)), (fr.px(1.0), fr.py(1.0))],
        "#bbbbbb",
        true,
    ));
    let mut names = Vec::new();
    for k in 0..NUM_MODELS {
        let pts = novelty_points(&rep.novelty, set, k);
        let curve: Vec<(f64, f64)> = roc_curve(&pts)
            .into_iter()
            .map(|(x, y)| (fr.px(x), fr.py(y)))
            .collect();
        s.push_str(&polyline(&curve, MODEL_COLOURS[k], false));
        let a = set_score(&rep.auc, set, k);
        names.push(format!("{} (AUC {a:.3})", MODELS[k]));
    }
    let items: Vec<(&str, &str)> = names
        .iter()
        .zip(MODEL_COLOURS)
        .map(|(n, c)| (n.as_str(), c))
        .collect();
    legend(&mut s, fr.left + fr.pw + 15.0, fr.top + 20.0, &items);
    s.push_str("</svg>\n");
    s
}

/// `map` with its classes replaced by the argmax of `probs`.
fn relabel(map: &TopoMap, probs: &[Vec<f64>]) -> TopoMap {
    let mut m = map.clone();
    for (i, w) in m.graph.node_weights_mut().enumerate() {
        let row = &probs[i];
        let best = (0..row.len())
            .max_by(|&a, &b| row[a].total_cmp(&row[b]).then(b.cmp(&a)))
            .unwrap_or(0);
        w.class = Some(best as crate::map::ClassId);
    }
    m
}

/// Width and height of a `render_svg` drawing (from its root element).
fn svg_size(svg: &str) -> (f64, f64) {
    let get = |key: &str| -> f64 {
        svg.find(&format!(" {key}=\""))
            .and_then(|i| {
                let rest = &svg[i + key.len() + 3..];
                rest.find('"').and_then(|j| rest[..j].parse().ok())
            })
            .unwrap_or(400.0)
    };
    (get("width"), get("height"))
}

/// Places the drawings side by side in one SVG (nested `<svg>` elements).
pub fn compose_side_by_side(drawings: &[String]) -> String {
    let sizes: Vec<(f64, f64)> = drawings.iter().map(|d| svg_size(d)).collect();
    let w: f64 = sizes.iter().map(|s| s.0).sum();
    let h = sizes.iter().map(|s| s.1).fold(0.0, f64::max);
    let mut s = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}">"#
    );
    s.push('\n');
    let mut x = 0.0;
    for (d, (dw, _)) in drawings.iter().zip(&sizes) {
        let body = d.replacen("<svg ", &format!(r#"<svg x="{x:.0}" y="0" "#), 1);
        s.push_str(&body);
        x += dw;
    }
    s.push_str("</svg>\n");
    s
}

fn wrong_places(o: &GraphOutcome) -> Vec<usize> {
    (0..o.evidence.wrong.len())
        .filter(|&i| o.evidence.wrong[i])
        .collect()
}

/// The labelled-map panel of one test map: ground truth, wrong evidence and each
/// model's labels (the paper's Fig. 8 layout).
pub(crate) fn fig8_panel(setup: &BuildingSetup, o: &GraphOutcome, level: NoiseLevel) -> String {
    let map = &setup.maps[0];
    let wrong = wrong_places(o);
    let templates = Template::paper_set();
    let acc = &o.result.accuracy;
    let d = [
        render_svg(
            map,
            &RenderOptions {
                title: Some(format!("{} ground truth", map.name)),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            map,
            &RenderOptions {
                title: Some(format!("{level}: wrong evidence (black), decomposition 1")),
                decomposition: setup.instances[0].decompositions().first(),
                templates: Some(&templates),
                highlight: &wrong,
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[TREES]),
            &RenderOptions {
                title: Some(format!("Tree mixture ({:.1}%)", 100.0 * acc[TREES])),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[GRAPHSPN]),
            &RenderOptions {
                title: Some(format!("GraphSPN ({:.1}%)", 100.0 * acc[GRAPHSPN])),
                ..RenderOptions::default()
            },
        ),
        render_svg(
            &relabel(map, &o.marginals[MRF2]),
            &RenderOptions {
                title: Some(format!("MRF-2 tuned ({:.1}%)", 100.0 * acc[MRF2])),
                ..RenderOptions::default()
            },
        ),
    ];
    compose_side_by_side(&d)
}

/// The placeholder panel of one test map: ground truth and the tree mixture's and
/// GraphSPN's placeholder marginals as pies.
pub(crate) fn pie_panel(map: &TopoMap, o: &GraphOutcome, level: NoiseLevel) -> String {
    let wrong = wrong_places(o);
    let mut d = vec![render_svg(
        map,
        &RenderOptions {
            title: Some(format!("{} ground truth (placeholders dashed)", map.name)),
            ..RenderOptions::default()
        },
    )];
    for k in [TREES, GRAPHSPN] {
        let dists = placeholder_pies(map, &o.marginals[k]);
        d.push(render_svg(
            map,
            &RenderOptions {
                title: Some(format!(
                    "{level}: {} placeholder marginals ({:.1}% correct)",
                    MODELS[k],
                    100.0 * o.result.accuracy[k]
                )),
                distributions: Some(&dists),
                highlight: &wrong,
                ..RenderOptions::default()
            },
        ));
    }
    compose_side_by_side(&d)
}

/// A pie per place: a placeholder's marginals, an explored place's true class.
fn placeholder_pies(map: &TopoMap, marginals: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let c = map.classes.len();
    map.places()
        .enumerate()
        .map(|(i, p)| {
            if p.placeholder {
                marginals[i].clone()
            } else {
                let mut v = vec![0.0; c];
                if let Some(k) = p.class {
                    v[k as usize] = 1.0;
                }
                v
            }
        })
        .collect()
}
