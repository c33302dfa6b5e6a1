//! The per-map part of the generated module: constants, the public API and the
//! chunked wiring that calls the shared template functions for every component.
//!
//! # Lane groups
//!
//! Components are deduplicated across decompositions (same template and places) and
//! ordered template by template. Components of a template with block kernels (see
//! `kernels.rs`) are evaluated in *lane groups* of 8 (`f32`) or 4 (`f64`): one call
//! computes the whole group, component `l` in SIMD lane `l`, so every weight is
//! broadcast once per group. The last group of a template is padded with copies of
//! its first component, whose results are ignored. Other templates (log space, or no
//! block structure) are evaluated one component per call.
//!
//! # Passes and memory
//!
//! No scratch array grows with the map except the caller's own buffers:
//! - *value pass* (`lp_chunk*`): every distinct component is evaluated once on its
//!   scaled evidence rows and its value multiplied (linear templates, in `f64`,
//!   flushed into a log before the product could underflow) or added (log templates)
//!   into `lp[d]` for every decomposition `d` containing it;
//! - *marginals*, single pass (when the scratch is at most [`super::CodegenOptions::max_stack_bytes`]):
//!   every distinct component is evaluated once with its backward sweep
//!   (`mg_chunk*`), its value accumulated into `lp` as above and its local posteriors
//!   `m_k[i][c] = x_i[c]·∂T_k/∂x_i[c] / T_k` kept in a stack scratch (one row per
//!   component place and lane, `Σ_k |k|·C` scalars plus padding: about 45 KB for a
//!   230-place map); once the decomposition posteriors
//!   `w_d = e^{ln(1/D) + lp_d − ln Ŝ}` are known, `sc_chunk*` adds
//!   `(Σ_{d ∋ k} w_d)·m_k` into `out`;
//! - *marginals*, two passes (larger maps): the value pass, then a posterior pass
//!   (`post_chunk*`) evaluating every distinct component again with its backward
//!   sweep and adding its weighted local posteriors into `out` directly. Recomputing
//!   the forward sweep costs about a third more arithmetic than storing per-component
//!   posteriors, which would need `D·N·C` scalars (2 MB at 10k places).
//! - MPE: a max-product value pass over every distinct component, then only the best
//!   decomposition's components are re-run (in lane groups of their own) with arg-max
//!   tracking and per-lane backtracking to write the labels.

use std::fmt::Write;

use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::TopoMap;

use super::CodegenOptions;
use super::analysis::{Numerics, Unique, numerics, unique_components};
use super::emit::{Lit, P};
use super::kernels::{self, KernelCode};
use super::template::TemplateCode;

/// `[p0, p1, ...]`: a component's place indices as an array literal.
fn places(p: &[usize]) -> String {
    let v: Vec<String> = p.iter().map(|x| x.to_string()).collect();
    format!("[{}]", v.join(", "))
}

fn sanitize(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    s.chars().take(24).collect()
}

/// A unit of wiring: a lane group of up to `L` components of one kernel template
/// (one SIMD call), or one component of a template without kernels.
#[derive(Clone, Debug)]
enum Item {
    /// Indices into the unique components; all of one template, at most `L`.
    Group(Vec<usize>),
    /// Index into the unique components.
    Single(usize),
}

impl Item {
    fn members(&self) -> &[usize] {
        match self {
            Item::Group(m) => m,
            Item::Single(u) => std::slice::from_ref(u),
        }
    }
}

/// Groups the unique components: template by template (in template order, components
/// in order of first appearance), kernel templates in lane groups of `lanes`.
fn items(uniques: &[Unique], grouped: &[bool], lanes: usize) -> Vec<Item> {
    let mut out = Vec::new();
    for (k, &g) in grouped.iter().enumerate() {
        let mine: Vec<usize> = (0..uniques.len())
            .filter(|&u| uniques[u].template == k)
            .collect();
        if g {
            out.extend(mine.chunks(lanes).map(|c| Item::Group(c.to_vec())));
        } else {
            out.extend(mine.into_iter().map(Item::Single));
        }
    }
    out
}

/// Splits items into consecutive chunks of at most `size` components (at least one
/// item each), as index ranges into `items`.
fn chunk_items(items: &[Item], size: usize) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let (mut start, mut count) = (0usize, 0usize);
    for (i, it) in items.iter().enumerate() {
        let n = it.members().len();
        if count > 0 && count + n > size {
            out.push(start..i);
            start = i;
            count = 0;
        }
        count += n;
    }
    if start < items.len() {
        out.push(start..items.len());
    }
    out
}

/// The place lists of a lane group as `[[p, ...], ...]`, padded to `lanes` rows by
/// repeating the first member (padding lanes are computed and ignored).
fn lane_places(uniques: &[Unique], members: &[usize], lanes: usize) -> String {
    let rows: Vec<String> = (0..lanes)
        .map(|l| places(&uniques[*members.get(l).unwrap_or(&members[0])].places))
        .collect();
    format!("[{}]", rows.join(", "))
}

/// Emits one chunk's value pass into `body`: each item's call (`call(item)`, a
/// statement binding `v`: an array of lane values for groups, a scalar otherwise),
/// then each member's value multiplied (linear templates, in `f64`, flushed into a log
/// before the product of lower bounds could drop below `1e-300`) or added (log
/// templates) into `lp[d]` for every decomposition `d` containing it. `max` selects
/// the max-product bounds.
fn value_chunk(
    chunk: &[Item],
    uniques: &[Unique],
    tpl: &[(String, Numerics)],
    d_count: usize,
    max: bool,
    call: &dyn Fn(&Item) -> String,
    body: &mut String,
) {
    // log10 of the current product bound, per decomposition.
    let mut bound = vec![0.0f64; d_count];
    let mut touched = vec![false; d_count];
    let uses_q = chunk
        .iter()
        .flat_map(Item::members)
        .any(|&u| matches!(tpl[uniques[u].template].1, Numerics::Linear { .. }));
    if uses_q {
        let _ = writeln!(body, "let mut q = [1.0f64; {d_count}];");
    }
    for it in chunk {
        let _ = writeln!(body, "let v = {};", call(it));
        for (lane, &ui) in it.members().iter().enumerate() {
            let u = &uniques[ui];
            let value = match it {
                Item::Group(_) => format!("f64::from(v[{lane}])"),
                Item::Single(_) => "f64::from(v)".to_string(),
            };
            match &tpl[u.template].1 {
                Numerics::Linear { min_value, min_max } => {
                    let lb = (if max { *min_max } else { *min_value }).log10();
                    for &d in &u.decs {
                        if bound[d] + lb < -300.0 {
                            let _ = writeln!(body, "lp[{d}] += {P}ln64(q[{d}]); q[{d}] = 1.0;");
                            bound[d] = 0.0;
                        }
                        bound[d] += lb;
                        touched[d] = true;
                        let _ = writeln!(body, "q[{d}] *= {value};");
                    }
                }
                Numerics::Log => {
                    for &d in &u.decs {
                        let _ = writeln!(body, "lp[{d}] += {value};");
                    }
                }
            }
        }
    }
    for (d, &tch) in touched.iter().enumerate() {
        if tch {
            let _ = writeln!(body, "lp[{d}] += {P}ln64(q[{d}]);");
        }
    }
}

/// Chunk functions per wiring module: rustc compiles each module as its own codegen
/// unit, so a large map's wiring builds in parallel and no single unit grows with
/// the map (one unit holding all the wiring made build time superlinear).
const CHUNKS_PER_PART: usize = 4;

/// The text of the wiring modules `wiring_<k>`, each holding the chunk functions
/// `k·CHUNKS_PER_PART .. (k+1)·CHUNKS_PER_PART` of every kind.
#[derive(Default)]
struct Parts(Vec<String>);

impl Parts {
    /// The text of the module holding chunk `j`.
    fn text(&mut self, j: usize) -> &mut String {
        let k = j / CHUNKS_PER_PART;
        if self.0.len() <= k {
            self.0.resize(k + 1, String::new());
        }
        &mut self.0[k]
    }

    /// Writes every module and a glob import of its functions into the parent.
    fn emit(&self, s: &mut String) {
        for (k, text) in self.0.iter().enumerate() {
            let _ = writeln!(
                s,
                "mod wiring_{k} {{ use super::*; {text} }} use wiring_{k}::*;"
            );
        }
    }
}

/// `w[d0] + w[d1] + ...`: the posterior weight of a component's decompositions.
fn weight_sum(u: &Unique) -> String {
    let ws: Vec<String> = u.decs.iter().map(|d| format!("w[{d}]")).collect();
    ws.join(" + ")
}

/// The whole module text (unformatted).
pub fn module(
    model: &Model,
    map: &TopoMap,
    decs: &[Decomposition],
    options: &CodegenOptions,
) -> String {
    let l = Lit::new(options.precision);
    let t = l.t;
    let n = map.num_places();
    let c = model.classes.len();
    let d_count = decs.len();
    let uniques = unique_components(decs);
    let mut used = vec![false; model.templates.len()];
    for u in &uniques {
        used[u.template] = true;
    }
    // Block structure of each used template (kernels), then linear or log space.
    let mut plans: Vec<Option<kernels::Plan>> = model
        .spns
        .iter()
        .zip(&used)
        .map(|(spn, &u)| if u { kernels::plan(spn, c) } else { None })
        .collect();
    let tpl: Vec<(String, Numerics)> = model
        .templates
        .iter()
        .zip(&model.spns)
        .enumerate()
        .map(|(k, (tp, spn))| {
            let num = if used[k] {
                numerics(spn, options.precision, plans[k].as_ref())
            } else {
                Numerics::Log
            };
            (format!("t{k}_{}", sanitize(&tp.name)), num)
        })
        .collect();
    // Kernels (SIMD lane groups) only for linear-space templates.
    for (plan, (_, num)) in plans.iter_mut().zip(&tpl) {
        if !matches!(num, Numerics::Linear { .. }) {
            *plan = None;
        }
    }
    let mut s = String::new();
    let ids: Vec<String> = map.places().map(|p| p.id.to_string()).collect();
    let names: Vec<String> = model
        .classes
        .names()
        .iter()
        .map(|x| format!("{x:?}"))
        .collect();
    let _ = write!(
        s,
        r#"
/// Number of places of the map (the length of every evidence array).
pub const NUM_PLACES: usize = {n};
/// Number of classes per place.
pub const NUM_CLASSES: usize = {c};
/// Number of decompositions mixed (with uniform weights) at the root.
pub const NUM_DECOMPOSITIONS: usize = {d_count};
/// User-facing id of each place, in place order (evidence row `p` is place `PLACE_IDS[p]`).
pub const PLACE_IDS: [u32; NUM_PLACES] = [{ids}];
/// Class names in class-index order.
pub const CLASS_NAMES: [&str; NUM_CLASSES] = [{names}];
/// The label meaning "unknown" in label arrays.
pub const UNKNOWN: u16 = u16::MAX;
/// Local evidence: one row of non-negative likelihoods (one per class) per place.
pub type Evidence = [[{t}; NUM_CLASSES]; NUM_PLACES];
/// Marginals: `P(Y_p = c | evidence)` per place and class.
pub type Marginals = [[{t}; NUM_CLASSES]; NUM_PLACES];
/// One class index per place (`UNKNOWN` = not labelled).
pub type Labels = [u16; NUM_PLACES];
static ALL_UNKNOWN: Labels = [UNKNOWN; NUM_PLACES];
"#,
        ids = ids.join(", "),
        names = names.join(", ")
    );
    let grouped: Vec<bool> = plans.iter().map(Option::is_some).collect();
    let lanes = kernels::lanes(&l);
    let lv = kernels::lane_type(&l);
    let items = items(&uniques, &grouped, lanes);
    // Single-pass marginals: every unique component's local posteriors kept in a
    // stack scratch of `rows` rows when it is small enough (lane groups take rows for
    // all their lanes, padding included).
    let mut offsets = vec![0usize; uniques.len()];
    let mut rows = 0usize;
    for it in &items {
        let width = uniques[it.members()[0]].places.len();
        for (lane, &u) in it.members().iter().enumerate() {
            offsets[u] = rows + lane * width;
        }
        rows += match it {
            Item::Group(_) => lanes * width,
            Item::Single(_) => width,
        };
    }
    let scalar = match options.precision {
        super::Precision::F32 => 4,
        super::Precision::F64 => 8,
    };
    let single_pass = rows * c * scalar <= options.max_stack_bytes;
    // Template functions.
    for (k, spn) in model.spns.iter().enumerate() {
        if !used[k] {
            continue;
        }
        let p = &tpl[k].0;
        let n = spn.num_vars();
        let _ = writeln!(
            s,
            "// template {k} ({:?}): {}",
            model.templates[k].name,
            match tpl[k].1 {
                Numerics::Linear { min_value, min_max } =>
                    format!("linear space, value ≥ {min_value:e}, max-product ≥ {min_max:e}"),
                Numerics::Log => "log space".into(),
            }
        );
        if let Some(plan) = &plans[k] {
            let kc = KernelCode {
                prefix: p.clone(),
                plan,
            };
            kc.statics(&l, &mut s);
            kc.fwdv(&l, &mut s);
            kc.postv(&l, &mut s);
            kc.mpvv(&l, &mut s);
            kc.mpev(&l, &mut s);
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_lwv(e: &Evidence, p: [[usize; {n}]; {lanes}], labels: &mut Labels) {{ let mut lab = [[0u16; {n}]; {lanes}]; {p}_mpev(&{P}gather_lanes_{t}(e, &ALL_UNKNOWN, p), &mut lab); {P}scatter_labels_lanes(labels, &lab, p); }}"
            );
            if !single_pass {
                let _ = writeln!(
                    s,
                    "#[inline(never)] fn {p}_pwv(e: &Evidence, w: [{t}; {lanes}], p: [[usize; {n}]; {lanes}], out: &mut Marginals) {{ let mut post = [[{lv}::ZERO; NUM_CLASSES]; {n}]; {p}_postv(&{P}gather_lanes_{t}(e, &ALL_UNKNOWN, p), &mut post); {P}scatter_lanes_{t}(out, w, &post, p); }}"
                );
            } else {
                let _ = writeln!(
                    s,
                    "#[inline(never)] fn {p}_pgv(e: &Evidence, p: [[usize; {n}]; {lanes}], g: &mut [[{t}; NUM_CLASSES]; {rows}], off: usize) -> [{t}; {lanes}] {{ let mut post = [[{lv}::ZERO; NUM_CLASSES]; {n}]; let v = {p}_postv(&{P}gather_lanes_{t}(e, &ALL_UNKNOWN, p), &mut post); {P}store_lanes_{t}(g, off, &post); v }}"
                );
            }
        } else {
            let code = TemplateCode {
                prefix: p.clone(),
                spn,
                numerics: tpl[k].1,
                classes: c,
            };
            code.statics(&l, &mut s);
            code.fwd(&l, &mut s);
            code.post(&l, &mut s);
            code.mpe(&l, &mut s);
            let _ = writeln!(
                s,
                "fn {p}_mpv(x: &[[{t}; {c}]; {n}]) -> {t} {{ let mut lab = [0u16; {n}]; {p}_mpe(x, &mut lab) }}"
            );
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_lw(e: &Evidence, p: [usize; {n}], labels: &mut Labels) {{ let mut lab = [0u16; {n}]; {p}_mpe(&{P}gather(e, &ALL_UNKNOWN, p), &mut lab); {P}scatter_labels(labels, &lab, p); }}"
            );
            if !single_pass {
                let _ = writeln!(
                    s,
                    "#[inline(never)] fn {p}_pw(e: &Evidence, w: {t}, p: [usize; {n}], out: &mut Marginals) {{ let mut g = [[0.0; NUM_CLASSES]; {n}]; {p}_post(&{P}gather(e, &ALL_UNKNOWN, p), &mut g); {P}scatter_post(out, w, &g, p); }}"
                );
            } else {
                let _ = writeln!(
                    s,
                    "#[inline(never)] fn {p}_pg(e: &Evidence, p: [usize; {n}], g: &mut [[{t}; NUM_CLASSES]; {rows}], off: usize) -> {t} {{ match {P}rows_mut(g, off) {{ Some(r) => {p}_post(&{P}gather(e, &ALL_UNKNOWN, p), r), None => 0.0 }} }}"
                );
            }
        }
        if single_pass {
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_sg(g: &[[{t}; NUM_CLASSES]; {rows}], off: usize, w: {t}, p: [usize; {n}], out: &mut Marginals) {{ if let Some(r) = {P}rows(g, off) {{ {P}scatter_post(out, w, r, p); }} }}"
            );
        }
    }
    let name_of = |it: &Item| &tpl[uniques[it.members()[0]].template].0;
    let chunks = chunk_items(&items, options.chunk_size);
    let mut parts = Parts::default();
    // Value passes.
    for (j, range) in chunks.iter().enumerate() {
        let ch = &items[range.clone()];
        for (max, name) in [(false, "lp"), (true, "mpv")] {
            let (fv, fs) = if max {
                ("mpvv", "mpv")
            } else {
                ("fwdv", "fwd")
            };
            let call = |it: &Item| match it {
                Item::Group(m) => format!(
                    "{}_{fv}(&{P}gather_lanes_{t}(e, labels, {}))",
                    name_of(it),
                    lane_places(&uniques, m, lanes)
                ),
                Item::Single(u) => format!(
                    "{}_{fs}(&{P}gather(e, labels, {}))",
                    name_of(it),
                    places(&uniques[*u].places)
                ),
            };
            let mut body = String::new();
            value_chunk(ch, &uniques, &tpl, d_count, max, &call, &mut body);
            let _ = writeln!(
                parts.text(j),
                "#[inline(never)] pub(super) fn {name}_chunk{j}(e: &Evidence, labels: &Labels, lp: &mut [f64; NUM_DECOMPOSITIONS]) {{ {body} }}"
            );
        }
        if single_pass {
            // Lane groups are identified by their first member's offset.
            let call = |it: &Item| match it {
                Item::Group(m) => format!(
                    "{}_pgv(e, {}, g, {})",
                    name_of(it),
                    lane_places(&uniques, m, lanes),
                    offsets[m[0]]
                ),
                Item::Single(u) => format!(
                    "{}_pg(e, {}, g, {})",
                    name_of(it),
                    places(&uniques[*u].places),
                    offsets[*u]
                ),
            };
            let mut body = String::new();
            value_chunk(ch, &uniques, &tpl, d_count, false, &call, &mut body);
            let _ = writeln!(
                parts.text(j),
                "#[inline(never)] pub(super) fn mg_chunk{j}(e: &Evidence, lp: &mut [f64; NUM_DECOMPOSITIONS], g: &mut [[{t}; NUM_CLASSES]; {rows}]) {{ {body} }}"
            );
            let mut body = String::new();
            for it in ch.iter() {
                for &u in it.members() {
                    let _ = writeln!(
                        body,
                        "{}_sg(g, {}, {}, {}, out);",
                        name_of(it),
                        offsets[u],
                        weight_sum(&uniques[u]),
                        places(&uniques[u].places)
                    );
                }
            }
            let _ = writeln!(
                parts.text(j),
                "#[inline(never)] pub(super) fn sc_chunk{j}(g: &[[{t}; NUM_CLASSES]; {rows}], w: &[{t}; NUM_DECOMPOSITIONS], out: &mut Marginals) {{ {body} }}"
            );
            continue;
        }
        // Posterior pass.
        let mut body = String::new();
        for it in ch.iter() {
            match it {
                Item::Group(m) => {
                    let ws: Vec<String> = (0..lanes)
                        .map(|lane| match m.get(lane) {
                            Some(&u) => weight_sum(&uniques[u]),
                            None => format!("0.0{t}"),
                        })
                        .collect();
                    let _ = writeln!(
                        body,
                        "{}_pwv(e, [{}], {}, out);",
                        name_of(it),
                        ws.join(", "),
                        lane_places(&uniques, m, lanes)
                    );
                }
                Item::Single(u) => {
                    let _ = writeln!(
                        body,
                        "{}_pw(e, {}, {}, out);",
                        name_of(it),
                        weight_sum(&uniques[*u]),
                        places(&uniques[*u].places)
                    );
                }
            }
        }
        let _ = writeln!(
            parts.text(j),
            "#[inline(never)] pub(super) fn post_chunk{j}(e: &Evidence, w: &[{t}; NUM_DECOMPOSITIONS], out: &mut Marginals) {{ {body} }}"
        );
    }
    // MPE labelling of one decomposition, chunked.
    let mut mpe_dispatch = String::new();
    let mut mpe_count = 0usize;
    for (d, dec) in decs.iter().enumerate() {
        // This decomposition's components, template by template; kernel templates in
        // lane groups (padded with copies of the first member, which write the same
        // labels again).
        let mut units: Vec<(usize, String)> = Vec::new();
        for (k, &g) in grouped.iter().enumerate() {
            let mine: Vec<&[usize]> = dec
                .components
                .iter()
                .filter(|comp| comp.template == k)
                .map(|comp| comp.places.as_slice())
                .collect();
            let name = &tpl[k].0;
            if g {
                for group in mine.chunks(lanes) {
                    let rows: Vec<String> = (0..lanes)
                        .map(|lane| places(group.get(lane).unwrap_or(&group[0])))
                        .collect();
                    units.push((
                        group.len(),
                        format!("{name}_lwv(e, [{}], labels);", rows.join(", ")),
                    ));
                }
            } else {
                for pl in mine {
                    units.push((1, format!("{name}_lw(e, {}, labels);", places(pl))));
                }
            }
        }
        let mut calls = Vec::new();
        let mut start = 0usize;
        let mut j = 0usize;
        while start < units.len() {
            let (mut end, mut count) = (start, 0usize);
            while end < units.len() && (count == 0 || count + units[end].0 <= options.chunk_size) {
                count += units[end].0;
                end += 1;
            }
            let body: String = units[start..end].iter().map(|u| u.1.as_str()).collect();
            mpe_count += 1;
            let _ = writeln!(
                parts.text(mpe_count - 1),
                "#[inline(never)] pub(super) fn mpe_d{d}_chunk{j}(e: &Evidence, labels: &mut Labels) {{ {body} }}"
            );
            calls.push(format!("mpe_d{d}_chunk{j}(e, labels);"));
            start = end;
            j += 1;
        }
        let _ = writeln!(mpe_dispatch, "{d} => {{ {} }}", calls.join(" "));
    }
    parts.emit(&mut s);
    let lp_calls: String = (0..chunks.len())
        .map(|j| format!("lp_chunk{j}(e, labels, &mut lp);"))
        .collect();
    let mpv_calls: String = (0..chunks.len())
        .map(|j| format!("mpv_chunk{j}(e, &ALL_UNKNOWN, &mut lp);"))
        .collect();
    let marginals_body = if single_pass {
        let mg_calls: String = (0..chunks.len())
            .map(|j| format!("mg_chunk{j}(e, &mut lp, &mut g);"))
            .collect();
        let sc_calls: String = (0..chunks.len())
            .map(|j| format!("sc_chunk{j}(&g, &w, out);"))
            .collect();
        format!(
            "let mut g = [[0.0{t}; NUM_CLASSES]; {rows}];
    let mut lp = [0.0f64; NUM_DECOMPOSITIONS];
    {mg_calls}
    let lhat = {P}lse64(&lp) + ln_inv_d();
    let l = {P}scale_{t}(e, &ALL_UNKNOWN) + lhat;
    if !(l > f64::NEG_INFINITY) {{
        return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
    }}
    let w = {P}weights_{t}(&lp, lhat);
    for row in out.iter_mut() {{
        *row = [0.0; NUM_CLASSES];
    }}
    {sc_calls}
    Ok(l as {t})"
        )
    } else {
        let post_calls: String = (0..chunks.len())
            .map(|j| format!("post_chunk{j}(e, &w, out);"))
            .collect();
        format!(
            "let lp = log_parts(e, &ALL_UNKNOWN);
    let lhat = {P}lse64(&lp) + ln_inv_d();
    let l = {P}scale_{t}(e, &ALL_UNKNOWN) + lhat;
    if !(l > f64::NEG_INFINITY) {{
        return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
    }}
    let w = {P}weights_{t}(&lp, lhat);
    for row in out.iter_mut() {{
        *row = [0.0; NUM_CLASSES];
    }}
    {post_calls}
    Ok(l as {t})"
        )
    };
    let _ = write!(
        s,
        r#"
/// `ln Π_k T_k(x)` of every decomposition for scaled (and label-masked) evidence.
fn log_parts(e: &Evidence, labels: &Labels) -> [f64; NUM_DECOMPOSITIONS] {{
    let mut lp = [0.0f64; NUM_DECOMPOSITIONS];
    {lp_calls}
    lp
}}

/// `ln(1/D)`.
fn ln_inv_d() -> f64 {{
    -{P}ln64(NUM_DECOMPOSITIONS as f64)
}}

/// Natural log of the likelihood `S(α)` of the evidence, without validating it.
/// Invalid evidence gives unspecified numbers (never a panic).
pub fn log_likelihood_unchecked(e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    labelled_log_likelihood_unchecked(&ALL_UNKNOWN, e)
}}

/// Natural log of the likelihood `S(α)` of the evidence (relative error about 1e-6 in
/// `f32`: per-template rounding, `f64` accumulation over components).
pub fn log_likelihood(e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    log_likelihood_unchecked(e)
}}

/// Like [`labelled_log_likelihood`], without validating evidence or labels.
pub fn labelled_log_likelihood_unchecked(labels: &Labels, e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    let scale = {P}scale_{t}(e, labels);
    let lp = log_parts(e, labels);
    let l = scale + {P}lse64(&lp) + ln_inv_d();
    if l > f64::NEG_INFINITY {{ Ok(l as {t}) }} else {{ Err(::graphspn_runtime::EvidenceError::ZeroLikelihood) }}
}}

/// Natural log of the likelihood of the evidence with every labelled place restricted
/// to its label (`UNKNOWN`: the whole row is used); labels `≥ NUM_CLASSES` are
/// rejected as `WrongShape {{ place, expected: NUM_CLASSES, found: label }}`.
pub fn labelled_log_likelihood(labels: &Labels, e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    {P}check_labels(labels, NUM_CLASSES)?;
    labelled_log_likelihood_unchecked(labels, e)
}}

/// Like [`marginals`], without validating the evidence.
pub fn marginals_unchecked(e: &Evidence, out: &mut Marginals) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {marginals_body}
}}

/// Writes the marginals `P(Y_p = c | α)` of every place into `out` (absolute error
/// about 1e-6 in `f32`) and returns the log-likelihood `ln S(α)`.
pub fn marginals(e: &Evidence, out: &mut Marginals) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    marginals_unchecked(e, out)
}}

/// Like [`mpe`], without validating the evidence.
pub fn mpe_unchecked(e: &Evidence, labels: &mut Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    let mut lp = [0.0f64; NUM_DECOMPOSITIONS];
    {mpv_calls}
    let best = {P}argmax64(&lp);
    let m = lp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let v = {P}scale_{t}(e, &ALL_UNKNOWN) + m + ln_inv_d();
    if !(v > f64::NEG_INFINITY) {{
        return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
    }}
    match best {{
        {mpe_dispatch}
        _ => {{}}
    }}
    Ok(v as {t})
}}

/// Writes the max-product (MPE) labelling into `labels` and returns its natural-log
/// max-product value `max_d ln((1/D) Π_k maxprod T_k)`, ties broken towards the lowest
/// decomposition and child index.
pub fn mpe(e: &Evidence, labels: &mut Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    mpe_unchecked(e, labels)
}}

/// This map as a [`::graphspn_runtime::CompiledMap`], for code generic over compiled maps.
pub struct Map;

impl ::graphspn_runtime::CompiledMap for Map {{
    type Scalar = {t};
    type Row = [{t}; NUM_CLASSES];
    const NUM_PLACES: usize = NUM_PLACES;
    const NUM_CLASSES: usize = NUM_CLASSES;
    const NUM_DECOMPOSITIONS: usize = NUM_DECOMPOSITIONS;
    const PLACE_IDS: &'static [u32] = &PLACE_IDS;
    const CLASS_NAMES: &'static [&'static str] = &CLASS_NAMES;
    const ZERO_ROW: Self::Row = [0.0; NUM_CLASSES];
    fn log_likelihood(e: &[Self::Row]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        self::log_likelihood({P}fixed(e)?)
    }}
    fn marginals(e: &[Self::Row], out: &mut [Self::Row]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        self::marginals({P}fixed(e)?, {P}fixed_mut(out)?)
    }}
    fn mpe(e: &[Self::Row], labels: &mut [u16]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        self::mpe({P}fixed(e)?, {P}fixed_mut(labels)?)
    }}
    fn labelled_log_likelihood(labels: &[u16], e: &[Self::Row]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        self::labelled_log_likelihood({P}fixed(labels)?, {P}fixed(e)?)
    }}
}}
"#
    );
    s
}
