//! The per-map part of the generated module: constants, the public API and the
//! chunked wiring that calls the shared template functions for every component.
//!
//! # Passes and memory
//!
//! No scratch array grows with the map except the caller's own buffers:
//! - *value pass* (`lp_chunk*`): every distinct component (same template and places,
//!   deduplicated across decompositions) is evaluated once on its scaled evidence
//!   rows and its value multiplied (linear templates, in `f64`, flushed into a log
//!   before the product could underflow) or added (log templates) into `lp[d]` for
//!   every decomposition `d` containing it;
//! - *marginals*, single pass (when the scratch is at most [`SINGLE_PASS_BYTES`]):
//!   every distinct component is evaluated once with its backward sweep
//!   (`mg_chunk*`), its value accumulated into `lp` as above and its local posteriors
//!   `m_k[i][c] = x_i[c]·∂T_k/∂x_i[c] / T_k` kept in a stack scratch (one row per
//!   component place, `Σ_k |k|·C` scalars: about 42 KB for a 230-place map); once the
//!   decomposition posteriors `w_d = e^{ln(1/D) + lp_d − ln Ŝ}` are known, `sc_chunk*`
//!   adds `(Σ_{d ∋ k} w_d)·m_k` into `out`;
//! - *marginals*, two passes (larger maps): the value pass, then a posterior pass
//!   (`post_chunk*`) evaluating every distinct component again with its backward
//!   sweep and adding its weighted local posteriors into `out` directly. Recomputing
//!   the forward sweep costs about a third more arithmetic than storing per-component
//!   posteriors, which would need `D·N·C` scalars (2 MB at 10k places).
//! - MPE: a max-product value pass, then only the best decomposition's components
//!   are re-run with backtracking to write the labels.

use std::fmt::Write;

use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::TopoMap;

use super::CodegenOptions;
use super::analysis::{Numerics, Unique, numerics, unique_components};
use super::emit::{Lit, P};
use super::kernels::{self, KernelCode};
use super::template::TemplateCode;

/// Largest stack scratch (bytes) for single-pass marginals: below it every unique
/// component's local posteriors are kept, so each component is evaluated once (forward
/// and backward); above it a value pass runs first and the posterior pass recomputes.
pub const SINGLE_PASS_BYTES: usize = 64 * 1024;

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

/// Emits the calls of one chunk's value pass into `body`.
///
/// `max` selects the max-product functions. Linear values are multiplied into
/// `q[d]` (`f64`) and flushed (`lp[d] += ln q[d]`) before the product of their lower
/// bounds could drop below `1e-300`.
fn value_chunk(
    chunk: &[Unique],
    tpl: &[(String, Numerics)],
    d_count: usize,
    max: bool,
    body: &mut String,
) {
    let f = if max { "mpv" } else { "fwd" };
    let call = |_: usize, u: &Unique| {
        format!(
            "{}_{f}(&{P}gather(e, labels, {}))",
            tpl[u.template].0,
            places(&u.places)
        )
    };
    value_chunk_with(chunk, tpl, d_count, max, &call, body);
}

/// [`value_chunk`] with the value expression of the `i`-th component of the chunk
/// given by `call(i, component)` (a template `fwd`, `mpv` or `post` call).
fn value_chunk_with(
    chunk: &[Unique],
    tpl: &[(String, Numerics)],
    d_count: usize,
    max: bool,
    call: &dyn Fn(usize, &Unique) -> String,
    body: &mut String,
) {
    // log10 of the current product bound, per decomposition.
    let mut bound = vec![0.0f64; d_count];
    let mut touched = vec![false; d_count];
    let uses_q = chunk
        .iter()
        .any(|u| matches!(tpl[u.template].1, Numerics::Linear { .. }));
    if uses_q {
        let _ = writeln!(body, "let mut q = [1.0f64; {d_count}];");
    }
    for (i, u) in chunk.iter().enumerate() {
        let (_, num) = &tpl[u.template];
        let _ = writeln!(body, "let v = f64::from({});", call(i, u));
        match num {
            Numerics::Linear { min_value, min_max } => {
                let lb = (if max { *min_max } else { *min_value }).log10();
                for &d in &u.decs {
                    if bound[d] + lb < -300.0 {
                        let _ = writeln!(body, "lp[{d}] += {P}ln64(q[{d}]); q[{d}] = 1.0;");
                        bound[d] = 0.0;
                    }
                    bound[d] += lb;
                    touched[d] = true;
                    let _ = writeln!(body, "q[{d}] *= v;");
                }
            }
            Numerics::Log => {
                for &d in &u.decs {
                    let _ = writeln!(body, "lp[{d}] += v;");
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
    let tpl: Vec<(String, Numerics)> = model
        .templates
        .iter()
        .zip(&model.spns)
        .enumerate()
        .map(|(k, (tp, spn))| {
            let num = if used[k] {
                numerics(spn, options.precision)
            } else {
                Numerics::Log
            };
            (format!("t{k}_{}", sanitize(&tp.name)), num)
        })
        .collect();
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
    // Single-pass marginals: every unique component's local posteriors kept in a
    // stack scratch of `rows` rows when it is small enough.
    let mut offsets = Vec::with_capacity(uniques.len());
    let mut rows = 0usize;
    for u in &uniques {
        offsets.push(rows);
        rows += u.places.len();
    }
    let scalar = match options.precision {
        super::Precision::F32 => 4,
        super::Precision::F64 => 8,
    };
    let single_pass = rows * c * scalar <= SINGLE_PASS_BYTES;
    // Template functions.
    for (k, spn) in model.spns.iter().enumerate() {
        if !used[k] {
            continue;
        }
        let code = TemplateCode {
            prefix: tpl[k].0.clone(),
            spn,
            numerics: tpl[k].1,
            classes: c,
        };
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
        let plan = match tpl[k].1 {
            Numerics::Linear { .. } => kernels::plan(spn, c),
            Numerics::Log => None,
        };
        if let Some(plan) = &plan {
            let kc = KernelCode {
                prefix: tpl[k].0.clone(),
                plan,
            };
            kc.statics(&l, &mut s);
            kc.fwd(&l, &mut s);
            kc.post(&l, &mut s);
            kc.mpv(&l, &mut s);
            kc.mpe(&l, &mut s);
        } else {
            code.statics(&l, &mut s);
            code.fwd(&l, &mut s);
            code.post(&l, &mut s);
            code.mpe(&l, &mut s);
            let _ = writeln!(
                s,
                "fn {p}_mpv(x: &[[{t}; {c}]; {n}]) -> {t} {{ let mut lab = [0u16; {n}]; {p}_mpe(x, &mut lab) }}",
                p = tpl[k].0,
                n = spn.num_vars()
            );
        }
        // Per-component entry points used by the wiring (one short call each).
        if single_pass {
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_pg(e: &Evidence, p: [usize; {n}], g: &mut [[{t}; NUM_CLASSES]; {rows}], off: usize) -> {t} {{ match {P}rows_mut(g, off) {{ Some(r) => {p}_post(&{P}gather(e, &ALL_UNKNOWN, p), r), None => 0.0 }} }}",
                p = tpl[k].0,
                n = spn.num_vars()
            );
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_sg(g: &[[{t}; NUM_CLASSES]; {rows}], off: usize, w: {t}, p: [usize; {n}], out: &mut Marginals) {{ if let Some(r) = {P}rows(g, off) {{ {P}scatter_post(out, w, r, p); }} }}",
                p = tpl[k].0,
                n = spn.num_vars()
            );
        } else {
            let _ = writeln!(
                s,
                "#[inline(never)] fn {p}_pw(e: &Evidence, w: {t}, p: [usize; {n}], out: &mut Marginals) {{ let mut g = [[0.0; NUM_CLASSES]; {n}]; {p}_post(&{P}gather(e, &ALL_UNKNOWN, p), &mut g); {P}scatter_post(out, w, &g, p); }}",
                p = tpl[k].0,
                n = spn.num_vars()
            );
        }
        let _ = writeln!(
            s,
            "#[inline(never)] fn {p}_lw(e: &Evidence, p: [usize; {n}], labels: &mut Labels) {{ let mut lab = [0u16; {n}]; {p}_mpe(&{P}gather(e, &ALL_UNKNOWN, p), &mut lab); {P}scatter_labels(labels, &lab, p); }}",
            p = tpl[k].0,
            n = spn.num_vars()
        );
    }
    let chunks: Vec<&[Unique]> = uniques.chunks(options.chunk_size).collect();
    let mut chunk_start = 0usize;
    // Value passes.
    for (j, ch) in chunks.iter().enumerate() {
        for (max, name) in [(false, "lp"), (true, "mpv")] {
            let mut body = String::new();
            value_chunk(ch, &tpl, d_count, max, &mut body);
            let _ = writeln!(
                s,
                "#[inline(never)] fn {name}_chunk{j}(e: &Evidence, labels: &Labels, lp: &mut [f64; NUM_DECOMPOSITIONS]) {{ {body} }}"
            );
        }
        if single_pass {
            let off = &offsets[chunk_start..chunk_start + ch.len()];
            let call = |i: usize, u: &Unique| {
                format!(
                    "{}_pg(e, {}, g, {})",
                    tpl[u.template].0,
                    places(&u.places),
                    off[i]
                )
            };
            let mut body = String::new();
            value_chunk_with(ch, &tpl, d_count, false, &call, &mut body);
            let _ = writeln!(
                s,
                "#[inline(never)] fn mg_chunk{j}(e: &Evidence, lp: &mut [f64; NUM_DECOMPOSITIONS], g: &mut [[{t}; NUM_CLASSES]; {rows}]) {{ {body} }}"
            );
            let mut body = String::new();
            for (u, o) in ch.iter().zip(off) {
                let ws: Vec<String> = u.decs.iter().map(|d| format!("w[{d}]")).collect();
                let _ = writeln!(
                    body,
                    "{}_sg(g, {o}, {}, {}, out);",
                    tpl[u.template].0,
                    ws.join(" + "),
                    places(&u.places)
                );
            }
            let _ = writeln!(
                s,
                "#[inline(never)] fn sc_chunk{j}(g: &[[{t}; NUM_CLASSES]; {rows}], w: &[{t}; NUM_DECOMPOSITIONS], out: &mut Marginals) {{ {body} }}"
            );
            chunk_start += ch.len();
            continue;
        }
        // Posterior pass.
        let mut body = String::new();
        for u in ch.iter() {
            let (name, _) = &tpl[u.template];
            let ws: Vec<String> = u.decs.iter().map(|d| format!("w[{d}]")).collect();
            let _ = writeln!(
                body,
                "{name}_pw(e, {}, {}, out);",
                ws.join(" + "),
                places(&u.places)
            );
        }
        let _ = writeln!(
            s,
            "#[inline(never)] fn post_chunk{j}(e: &Evidence, w: &[{t}; NUM_DECOMPOSITIONS], out: &mut Marginals) {{ {body} }}"
        );
    }
    // MPE labelling of one decomposition, chunked.
    let mut mpe_dispatch = String::new();
    for (d, dec) in decs.iter().enumerate() {
        let mut calls = Vec::new();
        for (j, ch) in dec.components.chunks(options.chunk_size).enumerate() {
            let mut body = String::new();
            for comp in ch {
                let (name, _) = &tpl[comp.template];
                let _ = writeln!(body, "{name}_lw(e, {}, labels);", places(&comp.places));
            }
            let _ = writeln!(
                s,
                "#[inline(never)] fn mpe_d{d}_chunk{j}(e: &Evidence, labels: &mut Labels) {{ {body} }}"
            );
            calls.push(format!("mpe_d{d}_chunk{j}(e, labels);"));
        }
        let _ = writeln!(mpe_dispatch, "{d} => {{ {} }}", calls.join(" "));
    }
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
