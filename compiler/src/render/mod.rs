//! SVG drawings of maps, per-place class distributions and decompositions.
//!
//! [`render_svg`](crate::render::render_svg) draws a [`TopoMap`](crate::map::TopoMap) at its poses (metres, y up): edges as
//! lines, places as discs coloured by class with a legend of class names,
//! placeholders as hollow dashed rings. Options add a title, a pie chart per
//! place (e.g. marginals), a colouring by decomposition component (template
//! colours with a legend; edges inside a component drawn thicker) and a set of
//! highlighted places drawn black. The SVG is hand-built, well-formed XML with
//! all text escaped, and deterministic.

use std::fmt::Write as _;

use crate::decompose::Decomposition;
use crate::map::TopoMap;
use crate::template::Template;

/// What to draw besides the map itself.
#[derive(Clone, Debug)]
pub struct RenderOptions<'a> {
    /// Title drawn above the map (escaped).
    pub title: Option<String>,
    /// Pixels per metre.
    pub scale: f64,
    /// Place radius in metres.
    pub radius: f64,
    /// Per-place class distributions (place order; each of length
    /// `map.classes.len()`, non-negative), drawn as pie charts.
    pub distributions: Option<&'a [Vec<f64>]>,
    /// A decomposition: places coloured by their component's template, edges
    /// inside a component drawn thicker.
    pub decomposition: Option<&'a Decomposition>,
    /// Template names for the decomposition legend (index = `Component::template`).
    pub templates: Option<&'a [Template]>,
    /// Place indices to highlight (drawn black), e.g. places with wrong evidence.
    pub highlight: &'a [usize],
    /// Edges `(a, b)` (place indices) of a spanning tree of a tree mixture, drawn
    /// thicker in dark blue.
    pub tree: Option<&'a [(u32, u32)]>,
}

impl Default for RenderOptions<'_> {
    fn default() -> Self {
        RenderOptions {
            title: None,
            scale: 40.0,
            radius: 0.22,
            distributions: None,
            decomposition: None,
            templates: None,
            highlight: &[],
            tree: None,
        }
    }
}

/// Why render options do not fit a map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// Not one distribution per place.
    #[error("{found} distributions for a map of {places} places")]
    DistributionCount {
        /// Distributions given.
        found: usize,
        /// Places in the map.
        places: usize,
    },
    /// A distribution of the wrong length or with a negative / non-finite entry.
    #[error("distribution of place index {index} (id {id}) is invalid: {why}")]
    BadDistribution {
        /// Place index.
        index: usize,
        /// Place id.
        id: u32,
        /// What is wrong.
        why: String,
    },
    /// A component or highlight names a place index outside the map.
    #[error("{what} names place index {index}, but the map has {places} places")]
    PlaceOutOfRange {
        /// Which option.
        what: &'static str,
        /// The index.
        index: usize,
        /// Places in the map.
        places: usize,
    },
    /// Non-positive or non-finite scale or radius.
    #[error("scale and radius must be positive and finite")]
    BadScale,
}

/// Check that `opts` fit `map` (distribution count and lengths, place indices).
pub fn check_options(map: &TopoMap, opts: &RenderOptions) -> Result<(), RenderError> {
    let n = map.num_places();
    if !(opts.scale.is_finite() && opts.scale > 0.0 && opts.radius.is_finite() && opts.radius > 0.0)
    {
        return Err(RenderError::BadScale);
    }
    if let Some(d) = opts.distributions {
        if d.len() != n {
            return Err(RenderError::DistributionCount {
                found: d.len(),
                places: n,
            });
        }
        for (i, v) in d.iter().enumerate() {
            let bad = |why: String| RenderError::BadDistribution {
                index: i,
                id: map.place(i).id,
                why,
            };
            if v.len() != map.classes.len() {
                return Err(bad(format!(
                    "{} entries for {} classes",
                    v.len(),
                    map.classes.len()
                )));
            }
            if v.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(bad("negative or non-finite entry".into()));
            }
        }
    }
    if let Some(dec) = opts.decomposition {
        for c in &dec.components {
            if let Some(&i) = c.places.iter().find(|&&i| i >= n) {
                return Err(RenderError::PlaceOutOfRange {
                    what: "a decomposition component",
                    index: i,
                    places: n,
                });
            }
        }
    }
    if let Some(&(a, b)) = opts
        .tree
        .unwrap_or(&[])
        .iter()
        .find(|&&(a, b)| a as usize >= n || b as usize >= n)
    {
        return Err(RenderError::PlaceOutOfRange {
            what: "the tree's edges",
            index: a.max(b) as usize,
            places: n,
        });
    }
    if let Some(&i) = opts.highlight.iter().find(|&&i| i >= n) {
        return Err(RenderError::PlaceOutOfRange {
            what: "the highlight set",
            index: i,
            places: n,
        });
    }
    Ok(())
}

/// Colour of class `c` (ten distinct colours, then evenly spaced hues).
pub fn class_colour(c: usize) -> String {
    const PALETTE: [&str; 10] = [
        "#d62728", // DW red
        "#7f7f7f", // CR grey
        "#1f77b4", // 1PO blue
        "#17becf", // 2PO cyan
        "#9467bd", // LO purple
        "#2ca02c", // LAB green
        "#e377c2", // BA pink
        "#ff7f0e", // KT orange
        "#bcbd22", // MR olive
        "#8c564b", // UT brown
    ];
    match PALETTE.get(c) {
        Some(s) => s.to_string(),
        None => format!("hsl({}, 65%, 45%)", (c * 137) % 360),
    }
}

/// Colour of template `t` in decomposition drawings.
pub fn template_colour(t: usize) -> String {
    const PALETTE: [&str; 6] = [
        "#4363d8", "#f58231", "#3cb44b", "#e6194b", "#911eb4", "#42d4f4",
    ];
    match PALETTE.get(t) {
        Some(s) => s.to_string(),
        None => format!("hsl({}, 70%, 50%)", (t * 97) % 360),
    }
}

/// Escape text for XML content and attribute values.
pub fn escape_xml(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\n' && c != '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// Draw `map` as a standalone SVG document.
///
/// Options that do not fit the map (see [`check_options`]) are not drawn; the
/// drawing then says so in a red warning line under the title, so a mismatch is
/// never silent. Call [`check_options`] first to treat it as an error.
pub fn render_svg(map: &TopoMap, opts: &RenderOptions) -> String {
    let mut warning = None;
    let mut opts = opts.clone();
    if let Err(e) = check_options(map, &opts) {
        warning = Some(e.to_string());
        if matches!(e, RenderError::BadScale) {
            opts.scale = RenderOptions::default().scale;
            opts.radius = RenderOptions::default().radius;
        }
        if check_options(
            map,
            &RenderOptions {
                decomposition: None,
                highlight: &[],
                ..opts.clone()
            },
        )
        .is_err()
        {
            opts.distributions = None;
        }
        if check_options(
            map,
            &RenderOptions {
                distributions: None,
                highlight: &[],
                ..opts.clone()
            },
        )
        .is_err()
        {
            opts.decomposition = None;
        }
        if check_options(
            map,
            &RenderOptions {
                distributions: None,
                decomposition: None,
                ..opts.clone()
            },
        )
        .is_err()
        {
            opts.highlight = &[];
        }
    }
    draw(map, &opts, warning.as_deref())
}

fn f(x: f64) -> String {
    let s = format!("{x:.2}");
    if s == "-0.00" { "0.00".into() } else { s }
}

/// Largest width or height (SVG user units) of the drawn map area: a map whose
/// extent times [`RenderOptions::scale`] is larger is drawn at the scale that fits
/// (so coordinates up to ±1.8e308 still give a finite drawing).
pub const MAX_EXTENT: f64 = 1e6;

fn draw(map: &TopoMap, opts: &RenderOptions, warning: Option<&str>) -> String {
    let n = map.num_places();
    let r = opts.radius * opts.scale;
    let (mut x0, mut x1, mut y0, mut y1) = (0.0f64, 1.0f64, 0.0f64, 1.0f64);
    if n > 0 {
        x0 = map.places().map(|p| p.x).fold(f64::INFINITY, f64::min);
        x1 = map.places().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
        y0 = map.places().map(|p| p.y).fold(f64::INFINITY, f64::min);
        y1 = map.places().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    }
    let margin = 20.0 + r;
    let top = margin
        + if opts.title.is_some() { 30.0 } else { 0.0 }
        + if warning.is_some() { 20.0 } else { 0.0 };
    // Half extents cannot overflow (x1 - x0 can, for coordinates near ±f64::MAX).
    let (half_w, half_h) = (x1 / 2.0 - x0 / 2.0, y1 / 2.0 - y0 / 2.0);
    let s = (MAX_EXTENT / 2.0 / half_w.max(half_h)).min(opts.scale);
    let map_w = half_w * s * 2.0;
    let map_h = half_h * s * 2.0;
    let legend_x = margin + map_w + r + 30.0;
    let legend_w = 170.0;

    // Component of every place, if a decomposition is drawn.
    let mut comp_of = vec![usize::MAX; n];
    let mut templ_of = vec![usize::MAX; n];
    if let Some(dec) = opts.decomposition {
        for (k, c) in dec.components.iter().enumerate() {
            for &i in &c.places {
                comp_of[i] = k;
                templ_of[i] = c.template;
            }
        }
    }
    let used_templates: std::collections::BTreeSet<usize> = opts
        .decomposition
        .map(|d| d.components.iter().map(|c| c.template).collect())
        .unwrap_or_default();
    let legend_rows = map.classes.len()
        + 2
        + if used_templates.is_empty() {
            0
        } else {
            used_templates.len() + 1
        };
    let legend_h = 20.0 * legend_rows as f64 + 20.0;
    let width = legend_x + legend_w;
    let height = (top + map_h + margin).max(top + legend_h);

    let px = |x: f64| margin + (x / 2.0 - x0 / 2.0) * s * 2.0;
    let py = |y: f64| top + (y1 / 2.0 - y / 2.0) * s * 2.0;

    let mut o = String::new();
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}" font-family="sans-serif" font-size="12">"#,
        f(width),
        f(height),
        f(width),
        f(height)
    );
    let _ = writeln!(o, r#"<rect width="100%" height="100%" fill="white"/>"#);
    if let Some(t) = &opts.title {
        let _ = writeln!(
            o,
            r#"<text class="title" x="{}" y="24" font-size="18">{}</text>"#,
            f(margin),
            escape_xml(t)
        );
    }
    if let Some(w) = warning {
        let _ = writeln!(
            o,
            r#"<text class="warning" x="{}" y="{}" fill="red">not drawn: {}</text>"#,
            f(margin),
            f(top - margin - 4.0),
            escape_xml(w)
        );
    }

    // Edges.
    let _ = writeln!(o, r#"<g id="edges" stroke-linecap="round">"#);
    let tree_edges: std::collections::BTreeSet<(usize, usize)> = opts
        .tree
        .unwrap_or(&[])
        .iter()
        .map(|&(a, b)| ((a.min(b)) as usize, (a.max(b)) as usize))
        .collect();
    for (a, b) in map.edge_list() {
        let (p, q) = (map.place(a), map.place(b));
        let inside =
            opts.decomposition.is_some() && comp_of[a] != usize::MAX && comp_of[a] == comp_of[b];
        let (stroke, w, class) = if tree_edges.contains(&(a, b)) {
            ("#1f3a93".to_string(), r * 0.35, "edge tree-edge")
        } else if inside {
            (
                template_colour(templ_of[a]),
                r * 0.45,
                "edge component-edge",
            )
        } else {
            ("#b0b0b0".to_string(), (r * 0.12).max(0.8), "edge")
        };
        let _ = writeln!(
            o,
            r#"<line class="{class}" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{stroke}" stroke-width="{}"/>"#,
            f(px(p.x)),
            f(py(p.y)),
            f(px(q.x)),
            f(py(q.y)),
            f(w)
        );
    }
    let _ = writeln!(o, "</g>");

    // Places.
    let highlighted: std::collections::BTreeSet<usize> = opts.highlight.iter().copied().collect();
    let _ = writeln!(o, r#"<g id="places">"#);
    for (i, p) in map.places().enumerate() {
        let (cx, cy) = (px(p.x), py(p.y));
        let class_name = p
            .class
            .map(|c| map.classes.name(c).to_string())
            .unwrap_or_else(|| "unlabelled".into());
        let mut tip = format!("place {} (index {i}): {class_name}", p.id);
        if p.placeholder {
            tip.push_str(", placeholder");
        }
        if comp_of[i] != usize::MAX {
            let _ = write!(
                tip,
                ", component {} ({})",
                comp_of[i],
                template_name(opts, templ_of[i])
            );
        }
        let class_fill = p
            .class
            .map(|c| class_colour(c as usize))
            .unwrap_or_else(|| "#ffffff".into());
        let fill = if highlighted.contains(&i) {
            "#000000".to_string()
        } else if opts.decomposition.is_some() && templ_of[i] != usize::MAX {
            template_colour(templ_of[i])
        } else {
            class_fill.clone()
        };
        let mut kind = String::from("place");
        if p.placeholder {
            kind.push_str(" placeholder");
        }
        if highlighted.contains(&i) {
            kind.push_str(" highlight");
        }
        let _ = writeln!(
            o,
            r#"<g class="{kind}" data-id="{}" data-index="{i}"><title>{}</title>"#,
            p.id,
            escape_xml(&tip)
        );
        match opts.distributions.map(|d| &d[i]) {
            Some(dist) if !highlighted.contains(&i) => pie(&mut o, cx, cy, r, dist),
            _ => {
                if p.placeholder && !highlighted.contains(&i) {
                    // Hollow dashed ring in the class (or template) colour.
                    let _ = writeln!(
                        o,
                        r#"<circle cx="{}" cy="{}" r="{}" fill="white" stroke="{fill}" stroke-width="{}" stroke-dasharray="{} {}"/>"#,
                        f(cx),
                        f(cy),
                        f(r * 0.85),
                        f(r * 0.3),
                        f(r * 0.35),
                        f(r * 0.25)
                    );
                } else {
                    let _ = writeln!(
                        o,
                        r##"<circle cx="{}" cy="{}" r="{}" fill="{fill}" stroke="#333333" stroke-width="0.6"/>"##,
                        f(cx),
                        f(cy),
                        f(r)
                    );
                }
            }
        }
        if p.placeholder && opts.distributions.is_some() {
            // Mark placeholders drawn as pies with a dashed outer ring.
            let _ = writeln!(
                o,
                r#"<circle cx="{}" cy="{}" r="{}" fill="none" stroke="black" stroke-width="1" stroke-dasharray="3 2"/>"#,
                f(cx),
                f(cy),
                f(r * 1.25)
            );
        }
        let _ = writeln!(o, "</g>");
    }
    let _ = writeln!(o, "</g>");

    // Legend.
    let _ = writeln!(o, r#"<g id="legend">"#);
    let mut y = top + 10.0;
    let _ = writeln!(
        o,
        r#"<text x="{}" y="{}" font-weight="bold">classes</text>"#,
        f(legend_x),
        f(y)
    );
    for (c, name) in map.classes.names().iter().enumerate() {
        y += 20.0;
        let _ = writeln!(
            o,
            r##"<circle class="legend-swatch" cx="{}" cy="{}" r="6" fill="{}" stroke="#333333" stroke-width="0.6"/><text x="{}" y="{}">{}</text>"##,
            f(legend_x + 6.0),
            f(y - 4.0),
            class_colour(c),
            f(legend_x + 18.0),
            f(y),
            escape_xml(name)
        );
    }
    y += 20.0;
    let _ = writeln!(
        o,
        r#"<circle cx="{}" cy="{}" r="5" fill="white" stroke="black" stroke-width="2" stroke-dasharray="3 2"/><text x="{}" y="{}">placeholder</text>"#,
        f(legend_x + 6.0),
        f(y - 4.0),
        f(legend_x + 18.0),
        f(y)
    );
    if !opts.highlight.is_empty() {
        y += 20.0;
        let _ = writeln!(
            o,
            r#"<circle cx="{}" cy="{}" r="6" fill="black"/><text x="{}" y="{}">highlighted</text>"#,
            f(legend_x + 6.0),
            f(y - 4.0),
            f(legend_x + 18.0),
            f(y)
        );
    }
    if !used_templates.is_empty() {
        y += 26.0;
        let _ = writeln!(
            o,
            r#"<text x="{}" y="{}" font-weight="bold">templates</text>"#,
            f(legend_x),
            f(y)
        );
        for &t in &used_templates {
            y += 20.0;
            let _ = writeln!(
                o,
                r#"<rect class="legend-template" x="{}" y="{}" width="12" height="12" fill="{}"/><text x="{}" y="{}">{}</text>"#,
                f(legend_x),
                f(y - 10.0),
                template_colour(t),
                f(legend_x + 18.0),
                f(y),
                escape_xml(&template_name(opts, t))
            );
        }
    }
    let _ = writeln!(o, "</g>");
    o.push_str("</svg>\n");
    o
}

fn template_name(opts: &RenderOptions, t: usize) -> String {
    opts.templates
        .and_then(|ts| ts.get(t))
        .map(|tp| tp.name.clone())
        .unwrap_or_else(|| format!("template {t}"))
}

/// A pie chart of `dist` (normalised here) at `(cx, cy)` with radius `r`.
fn pie(o: &mut String, cx: f64, cy: f64, r: f64, dist: &[f64]) {
    let total: f64 = dist.iter().sum();
    if total <= 0.0 {
        let _ = writeln!(
            o,
            r##"<circle cx="{}" cy="{}" r="{}" fill="#ffffff" stroke="#333333"/>"##,
            f(cx),
            f(cy),
            f(r)
        );
        return;
    }
    let mut angle = -std::f64::consts::FRAC_PI_2;
    for (c, &v) in dist.iter().enumerate() {
        let share = v / total;
        if share <= 0.0 {
            continue;
        }
        if share >= 0.9999 {
            let _ = writeln!(
                o,
                r#"<circle cx="{}" cy="{}" r="{}" fill="{}"/>"#,
                f(cx),
                f(cy),
                f(r),
                class_colour(c)
            );
            angle += std::f64::consts::TAU * share;
            continue;
        }
        let a1 = angle + std::f64::consts::TAU * share;
        let large = if share > 0.5 { 1 } else { 0 };
        let _ = writeln!(
            o,
            r#"<path d="M{} {} L{} {} A{} {} 0 {large} 1 {} {} Z" fill="{}"/>"#,
            f(cx),
            f(cy),
            f(cx + r * angle.cos()),
            f(cy + r * angle.sin()),
            f(r),
            f(r),
            f(cx + r * a1.cos()),
            f(cy + r * a1.sin()),
            class_colour(c)
        );
        angle = a1;
    }
    let _ = writeln!(
        o,
        r##"<circle cx="{}" cy="{}" r="{}" fill="none" stroke="#333333" stroke-width="0.6"/>"##,
        f(cx),
        f(cy),
        f(r)
    );
}
