//! The per-map part of the generated module: constants, the component tables of
//! every template, the public stateless API and the streaming [`State`] type.
//!
//! # Shape
//!
//! Components are deduplicated across decompositions (same template and places) and
//! listed template by template in `static` tables: each template's components in
//! groups of `L` (one per lane of the module's vector type `V`: `L = 1` on targets
//! without float SIMD, 8 (`f32`) or 4 (`f64`) on the host; the last group padded with
//! its first member), and per component the bit set of decompositions containing it.
//! The generic driver `graphspn_runtime::__private::engine` runs over those tables and
//! calls the template's straight-line functions (`sparse.rs`, or `template.rs` for
//! templates without block structure), so the per-map code is a few calls whatever
//! the map's size: only the tables grow with the map.
//!
//! # Passes and memory
//!
//! - value pass: every distinct component once; its value multiplied into the
//!   accumulator (`Acc`: mantissa and exact power of two) of every decomposition
//!   containing it;
//! - marginals (stateless): the value pass, then a posterior pass evaluating every
//!   component again with its backward sweep and adding its weighted local
//!   posteriors into the output (no scratch that grows with the map);
//! - MPE: a max-product value pass, then the best decomposition's components with
//!   backtracking;
//! - [`State`]: the caller owns per component its value and local posteriors, so an
//!   update of one place re-evaluates only the groups containing it.

use std::fmt::Write;

use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::TopoMap;

use super::analysis::{Numerics, numerics, unique_components};
use super::emit::Lit;
const P: &str = "::graphspn_runtime::__private::";
use super::kernels;
use super::sparse::{Counts, SparseCode};
use super::template::TemplateCode;
use super::{CodegenError, CodegenOptions, Precision, Vectorisation};

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

/// What the generator knows about the generated code, beside its text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CodeReport {
    /// Components per call of kernel templates (`1` on targets without float SIMD).
    pub lanes: usize,
    /// Distinct components of the map.
    pub components: usize,
    /// Upper bound of the stack of `log_likelihood` (bytes), kernel frames included.
    pub stack_log_likelihood: usize,
    /// Upper bound of the stack of `marginals` (bytes).
    pub stack_marginals: usize,
    /// Upper bound of the stack of `mpe` (bytes).
    pub stack_mpe: usize,
    /// Upper bound of the stack of a [`State`] update plus query (bytes).
    pub stack_state: usize,
    /// Size of the streaming state (bytes).
    pub state_bytes: usize,
    /// Bytes of the `static` tables (component places, decomposition sets, slots).
    pub table_bytes: usize,
    /// Multiply(-add)s of one `log_likelihood` call (lane-vector operations).
    pub macs_log_likelihood: usize,
    /// Multiply(-add)s of one `marginals` call.
    pub macs_marginals: usize,
    /// Multiply(-add)s of one `mpe` call.
    pub macs_mpe: usize,
    /// Worst-case multiply(-add)s of one state update (`observe`) plus `marginals`.
    pub macs_observe_marginals: usize,
    /// Mean number of evaluation units (lane groups; single components in scalar
    /// code) one state update re-evaluates, over the places.
    pub units_per_update: f64,
}

/// One template as generated: its function prefix, lanes, numerics and counts.
struct Tpl {
    prefix: String,
    /// Components per call.
    lanes: usize,
    /// Lane type in the generated code (`V` or the scalar).
    w: &'static str,
    vars: usize,
    numerics: Numerics,
    counts: Counts,
    /// Extra stack of its functions beyond the arrays the driver holds (bytes).
    frame: usize,
    /// Indices into the unique components, in order.
    members: Vec<usize>,
}

impl Tpl {
    fn groups(&self) -> usize {
        self.members.len().div_ceil(self.lanes)
    }
}

/// The whole module text (unformatted) and its report.
pub fn module(
    model: &Model,
    map: &TopoMap,
    decs: &[Decomposition],
    options: &CodegenOptions,
) -> Result<(String, CodeReport), CodegenError> {
    let l = Lit::new(options.precision);
    let t = l.t;
    let n = map.num_places();
    let c = model.classes.len();
    let d_count = decs.len();
    if n > usize::from(u16::MAX) {
        return Err(CodegenError::BadOption(format!(
            "at most 65,535 places can be compiled, the map has {n}"
        )));
    }
    if d_count > 64 {
        return Err(CodegenError::BadOption(format!(
            "at most 64 decompositions can be compiled, got {d_count}"
        )));
    }
    let scalar = match options.precision {
        Precision::F32 => 4,
        Precision::F64 => 8,
    };
    let simd_lanes = match (options.vectorisation, options.precision) {
        (Vectorisation::Scalar, _) => 1,
        (Vectorisation::Simd, Precision::F32) => 8,
        (Vectorisation::Simd, Precision::F64) => 4,
    };
    let uniques = unique_components(decs);
    let mut s = String::new();
    let mut tpls: Vec<Tpl> = Vec::new();
    let mut fns = String::new();
    for (k, spn) in model.spns.iter().enumerate() {
        let mut members: Vec<usize> = (0..uniques.len())
            .filter(|&u| uniques[u].template == k)
            .collect();
        // Lane groups of neighbouring components: the components of different
        // decompositions that contain a place then tend to share a group, so a
        // streaming update re-evaluates fewer groups.
        members.sort_by_key(|&u| (uniques[u].places.iter().min().copied(), u));
        if members.is_empty() {
            continue;
        }
        let prefix = format!("t{k}_{}", sanitize(&model.templates[k].name));
        let plan = kernels::plan(spn, c);
        let num = numerics(spn, options.precision, plan.as_ref());
        let vars = spn.num_vars();
        let _ = writeln!(
            fns,
            "// template {k} ({:?}): {}",
            model.templates[k].name,
            match num {
                Numerics::Linear { min_value, min_max } =>
                    format!("linear space, value ≥ {min_value:e}, max-product ≥ {min_max:e}"),
                Numerics::Log => "log space".into(),
            }
        );
        let tpl = match (&plan, num) {
            (Some(plan), Numerics::Linear { .. }) => {
                let code = SparseCode {
                    prefix: prefix.clone(),
                    plan,
                };
                let mut emitted = |(tokens, ops): (proc_macro2::TokenStream, usize)| {
                    let _ = writeln!(fns, "{tokens}");
                    ops
                };
                let counts = Counts {
                    fwd: emitted(code.fwd(&l)),
                    post: emitted(code.post(&l)),
                    max: emitted(code.max(&l)),
                    mpe: emitted(code.mpe(&l)),
                };
                let sums: usize = plan.blocks.iter().map(|b| b.sums.len()).sum();
                // Block values and adjoints, variable adjoints, MPE arguments and
                // selections, and room for spills of the straight-line temporaries
                // (Cortex-M4F, 230-place map: the Star's MPE function has a 4.1 KB
                // frame, its posterior function 2.2 KB).
                let frame = (2 * sums + vars * c) * simd_lanes * scalar + 10 * sums + 4096;
                Tpl {
                    prefix,
                    lanes: simd_lanes,
                    w: "V",
                    vars,
                    numerics: num,
                    counts,
                    frame,
                    members,
                }
            }
            _ => {
                let code = TemplateCode {
                    prefix: prefix.clone(),
                    spn,
                    numerics: num,
                    classes: c,
                };
                for tokens in [
                    code.statics(&l),
                    code.fwd(&l),
                    code.post(&l),
                    code.mpe(&l),
                    code.max(&l),
                ] {
                    let _ = writeln!(fns, "{tokens}");
                }
                let edges: usize = spn
                    .nodes
                    .iter()
                    .map(|nd| match nd {
                        crate::spn::Node::Sum { children, .. }
                        | crate::spn::Node::Product { children } => children.len(),
                        crate::spn::Node::Leaf { .. } => 0,
                    })
                    .sum();
                // One value per node (and one adjoint), plus spills.
                let frame = 2 * spn.nodes.len() * scalar + 2048;
                Tpl {
                    prefix,
                    lanes: 1,
                    w: t,
                    vars,
                    numerics: num,
                    counts: Counts {
                        fwd: edges,
                        post: 3 * edges,
                        max: edges,
                        mpe: edges,
                    },
                    frame,
                    members,
                }
            }
        };
        tpls.push(tpl);
    }
    // Tables.
    let mut tables = String::new();
    let mut table_bytes = 0usize;
    // Global numbering: component offsets, posterior-row offsets, group offsets.
    let mut comp_of = vec![(0usize, 0usize); uniques.len()]; // (template slot, index)
    let (mut uo, mut ro, mut go) = (Vec::new(), Vec::new(), Vec::new());
    let (mut u_total, mut rows, mut groups) = (0usize, 0usize, 0usize);
    for (ti, tp) in tpls.iter().enumerate() {
        uo.push(u_total);
        ro.push(rows);
        go.push(groups);
        for (i, &u) in tp.members.iter().enumerate() {
            comp_of[u] = (ti, i);
        }
        u_total += tp.members.len();
        rows += tp.members.len() * tp.vars;
        groups += tp.groups();
        let name = tp.prefix.to_uppercase();
        let lanes = tp.lanes;
        let group_text: Vec<String> = (0..tp.groups())
            .map(|g| {
                let lanes_text: Vec<String> = (0..lanes)
                    .map(|ln| {
                        let u = tp
                            .members
                            .get(g * lanes + ln)
                            .unwrap_or(&tp.members[g * lanes]);
                        let ps: Vec<String> =
                            uniques[*u].places.iter().map(|p| p.to_string()).collect();
                        format!("[{}]", ps.join(", "))
                    })
                    .collect();
                format!("[{}]", lanes_text.join(", "))
            })
            .collect();
        let masks: Vec<String> = tp
            .members
            .iter()
            .map(|&u| {
                let m: u64 = uniques[u].decs.iter().map(|&d| 1u64 << d).sum();
                format!("{m:#x}")
            })
            .collect();
        table_bytes += tp.groups() * lanes * tp.vars * 2 + tp.members.len() * 8;
        let _ = writeln!(
            tables,
            "static {name}_PLACES: [[[u16; {v}]; {lanes}]; {g}] = [{}];",
            group_text.join(", "),
            v = tp.vars,
            g = tp.groups()
        );
        let _ = writeln!(
            tables,
            "static {name}_DECS: [u64; {}] = [{}];",
            tp.members.len(),
            masks.join(", ")
        );
        let _ = writeln!(
            tables,
            "static {name}: {P}Tpl<{w}, {lanes}, {v}, {c}> = {P}Tpl {{ places: &{name}_PLACES, decs: &{name}_DECS, log: {log}, fwd: {p}_fwd, post: {p}_post, max: {p}_max, mpe: {p}_mpe }};",
            w = tp.w,
            v = tp.vars,
            log = matches!(tp.numerics, Numerics::Log),
            p = tp.prefix
        );
    }
    // Per place: the global groups containing it, and per decomposition the
    // posterior row of the place in that decomposition's component.
    let mut place_units: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut place_slots: Vec<Vec<u32>> = vec![vec![u32::MAX; d_count]; n];
    for (u, un) in uniques.iter().enumerate() {
        let (ti, i) = comp_of[u];
        let tp = &tpls[ti];
        let unit = go[ti] + i / tp.lanes;
        for (v, &p) in un.places.iter().enumerate() {
            if !place_units[p].contains(&unit) {
                place_units[p].push(unit);
            }
            let row = (ro[ti] + i * tp.vars + v) as u32;
            for &d in &un.decs {
                place_slots[p][d] = row;
            }
        }
    }
    let max_units = place_units.iter().map(Vec::len).max().unwrap_or(0).max(1);
    let unit_t = if groups < usize::from(u16::MAX) {
        "u16"
    } else {
        "u32"
    };
    let units_text: Vec<String> = place_units
        .iter()
        .map(|us| {
            let mut v: Vec<String> = us.iter().map(|u| u.to_string()).collect();
            v.resize(max_units, format!("{unit_t}::MAX"));
            format!("[{}]", v.join(", "))
        })
        .collect();
    let slots_text: Vec<String> = place_slots
        .iter()
        .map(|ss| {
            let v: Vec<String> = ss.iter().map(|s| s.to_string()).collect();
            format!("[{}]", v.join(", "))
        })
        .collect();
    table_bytes += n * max_units * 2 + n * d_count * 4;
    let _ = writeln!(
        tables,
        "/// Per place: the groups of components containing it (`u16::MAX`: none).\nstatic PLACE_UNITS: [[{unit_t}; {max_units}]; NUM_PLACES] = [{}];",
        units_text.join(", ")
    );
    let _ = writeln!(
        tables,
        "/// Per place and decomposition: the place's row in the state's posteriors.\nstatic PLACE_SLOTS: [[u32; NUM_DECOMPOSITIONS]; NUM_PLACES] = [{}];",
        slots_text.join(", ")
    );
    // Driver calls, one per template.
    let each = |f: &dyn Fn(usize, &Tpl) -> String| -> String {
        tpls.iter().enumerate().map(|(ti, tp)| f(ti, tp)).collect()
    };
    let value_calls = each(&|_, tp| {
        format!(
            "{P}value_pass(&{}, e, labels, max, &mut acc);\n",
            tp.prefix.to_uppercase()
        )
    });
    let post_calls = each(&|_, tp| {
        format!(
            "{P}posterior_pass(&{}, e, &w, out);\n",
            tp.prefix.to_uppercase()
        )
    });
    let mpe_calls = each(&|_, tp| {
        format!(
            "{P}mpe_labels(&{}, e, d, labels);\n",
            tp.prefix.to_uppercase()
        )
    });
    let refresh_calls = each(&|ti, tp| {
        format!(
            "for g in 0..{} {{ self.eval_group_{ti}(g); }}\n",
            tp.groups()
        )
    });
    let eval_fns = each(&|ti, tp| {
        format!(
            "#[inline(never)] fn eval_group_{ti}(&mut self, g: usize) {{ if let (Some(v), Some(p)) = (self.val.get_mut({}..), self.post.get_mut({}..)) {{ {P}eval_group(&{}, &self.ev, g, v, p); }} }}\n",
            uo[ti],
            ro[ti],
            tp.prefix.to_uppercase()
        )
    });
    let mut dispatch = String::new();
    for (ti, tp) in tpls.iter().enumerate() {
        let _ = write!(
            dispatch,
            "if unit < {} {{ self.eval_group_{ti}(unit - {}); }} else ",
            go[ti] + tp.groups(),
            go[ti]
        );
    }
    dispatch.push_str("{}");
    let state_value_calls = each(&|ti, tp| {
        format!(
            "if let Some(v) = self.val.get({}..) {{ {P}state_values(&{}, v, &mut acc); }}\n",
            uo[ti],
            tp.prefix.to_uppercase()
        )
    });
    let state_marginal_calls = each(&|ti, tp| {
        format!(
            "if let Some(p) = self.post.get({}..) {{ {P}state_marginals(&{}, p, &self.w, out); }}\n",
            ro[ti],
            tp.prefix.to_uppercase()
        )
    });
    // Report: stack, memory, multiply-adds.
    // Driver frame: the gathered inputs and the posteriors (`vars × classes` vectors
    // each), the gather's per-lane row sources (a reference, a scale and a tag: 24
    // bytes), one variable's posteriors as `classes × lanes` scalars, and 512 bytes.
    let driver = |tp: &Tpl| {
        2 * tp.vars * c * tp.lanes * scalar + tp.vars * tp.lanes * 24 + c * tp.lanes * scalar + 512
    };
    let deepest = tpls
        .iter()
        .map(|tp| driver(tp) + tp.frame)
        .max()
        .unwrap_or(0);
    let top = d_count * 32 + 1024;
    let state_bytes =
        n * c * scalar + n * scalar + u_total * scalar + rows * c * scalar + d_count * scalar + 16;
    let per_groups =
        |f: &dyn Fn(&Tpl) -> usize| -> usize { tpls.iter().map(|tp| tp.groups() * f(tp)).sum() };
    let macs_ll = per_groups(&|tp| tp.counts.fwd);
    let macs_marg = macs_ll + per_groups(&|tp| tp.counts.post) + rows * c;
    let macs_mpe = per_groups(&|tp| tp.counts.max)
        + tpls
            .iter()
            .map(|tp| tp.members.len().div_ceil(d_count.max(1)) * tp.counts.mpe)
            .sum::<usize>();
    let worst_update = (0..n)
        .map(|p| {
            place_units[p]
                .iter()
                .map(|&unit| {
                    let ti = go.iter().rposition(|&g| g <= unit).unwrap_or(0);
                    tpls[ti].counts.post
                })
                .sum::<usize>()
        })
        .max()
        .unwrap_or(0);
    let report = CodeReport {
        lanes: simd_lanes,
        components: uniques.len(),
        stack_log_likelihood: top + deepest,
        stack_marginals: top
            + d_count * scalar
            + deepest
            + tpls
                .iter()
                .map(|tp| tp.vars * c * tp.lanes * scalar)
                .max()
                .unwrap_or(0),
        stack_mpe: top + deepest,
        stack_state: top + deepest,
        state_bytes,
        table_bytes,
        macs_log_likelihood: macs_ll,
        macs_marginals: macs_marg,
        macs_mpe,
        macs_observe_marginals: worst_update + u_total * 2 + rows * c,
        units_per_update: place_units.iter().map(Vec::len).sum::<usize>() as f64 / n.max(1) as f64,
    };
    let worst = report
        .stack_marginals
        .max(report.stack_log_likelihood)
        .max(report.stack_mpe)
        .max(report.stack_state);
    if worst > options.stack_budget() {
        return Err(CodegenError::BadOption(format!(
            "the generated code needs up to {worst} bytes of stack per call, more than the budget of {} bytes (max_stack_bytes)",
            options.stack_budget()
        )));
    }
    let ids: Vec<String> = map.places().map(|p| p.id.to_string()).collect();
    let names: Vec<String> = model
        .classes
        .names()
        .iter()
        .map(|x| format!("{x:?}"))
        .collect();
    let v_type = if simd_lanes == 1 {
        t.to_string()
    } else if t == "f32" {
        format!("{P}Lanes32")
    } else {
        format!("{P}Lanes64")
    };
    // The lane vector, for the block templates' functions (none: every template has
    // per-node code).
    let lane_items = if tpls.iter().any(|tp| tp.w == "V") {
        format!("use {P}Lanes as _;\n/// The lane vector of block templates.\ntype V = {v_type};\n")
    } else {
        String::new()
    };
    let _ = write!(
        s,
        r#"
{lane_items}
/// Number of places of the map (the length of every evidence array).
pub const NUM_PLACES: usize = {n};
/// Number of classes per place.
pub const NUM_CLASSES: usize = {c};
/// Number of decompositions mixed (with uniform weights) at the root.
pub const NUM_DECOMPOSITIONS: usize = {d_count};
/// Components evaluated per call of a template function (SIMD lanes; 1 = scalar code).
pub const LANES: usize = {simd_lanes};
/// Distinct components (template copies) of the map.
pub const NUM_COMPONENTS: usize = {u_total};
/// Upper bound of the stack (bytes) of one `log_likelihood` or `labelled_log_likelihood` call.
pub const STACK_BYTES_LOG_LIKELIHOOD: usize = {sl};
/// Upper bound of the stack (bytes) of one `marginals` call.
pub const STACK_BYTES_MARGINALS: usize = {sm};
/// Upper bound of the stack (bytes) of one `mpe` call.
pub const STACK_BYTES_MPE: usize = {sp};
/// Upper bound of the stack (bytes) of one [`State`] update or query.
pub const STACK_BYTES_STATE: usize = {ss};
/// Bytes of one [`State`].
pub const STATE_BYTES: usize = core::mem::size_of::<State>();
/// Multiply(-add)s of one `log_likelihood` call (vector operations when `LANES > 1`).
pub const MACS_LOG_LIKELIHOOD: usize = {ml};
/// Multiply(-add)s of one `marginals` call.
pub const MACS_MARGINALS: usize = {mm};
/// Multiply(-add)s of one `mpe` call.
pub const MACS_MPE: usize = {mp};
/// Worst-case multiply(-add)s of one [`State::observe`] plus [`State::marginals`].
pub const MACS_OBSERVE_MARGINALS: usize = {mo};
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
const NUM_ROWS: usize = {rows};
{fns}
{tables}

/// The decomposition accumulators of a value pass (`max`: max-product values).
fn values(e: &Evidence, labels: &Labels, max: bool) -> [{P}Acc<{t}>; NUM_DECOMPOSITIONS] {{
    let mut acc = [{P}Acc::ONE; NUM_DECOMPOSITIONS];
    {value_calls}
    acc
}}

/// `ln S` from the decomposition accumulators and the evidence scale.
fn finish(acc: &[{P}Acc<{t}>; NUM_DECOMPOSITIONS], scale: {t}) -> Result<({t}, [{t}; NUM_DECOMPOSITIONS]), ::graphspn_runtime::EvidenceError> {{
    match {P}mix(acc) {{
        Some((l, w)) if scale + l > {t}::NEG_INFINITY => Ok((scale + l, w)),
        _ => Err(::graphspn_runtime::EvidenceError::ZeroLikelihood),
    }}
}}

/// Natural log of the likelihood `S(α)` of the evidence, without validating it.
/// Invalid evidence gives unspecified numbers (never a panic).
pub fn log_likelihood_unchecked(e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    labelled_log_likelihood_unchecked(&ALL_UNKNOWN, e)
}}

/// Natural log of the likelihood `S(α)` of the evidence (relative error about 1e-6 in
/// `f32`: one rounding per multiply-add, products kept with exact exponents).
pub fn log_likelihood(e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    log_likelihood_unchecked(e)
}}

/// Like [`labelled_log_likelihood`], without validating evidence or labels.
pub fn labelled_log_likelihood_unchecked(labels: &Labels, e: &Evidence) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    let acc = values(e, labels, false);
    finish(&acc, {P}log_scale(e, labels)).map(|(l, _)| l)
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
    let acc = values(e, &ALL_UNKNOWN, false);
    let (l, w) = finish(&acc, {P}log_scale(e, &ALL_UNKNOWN))?;
    for row in out.iter_mut() {{
        *row = [0.0; NUM_CLASSES];
    }}
    {post_calls}
    Ok(l)
}}

/// Writes the marginals `P(Y_p = c | α)` of every place into `out` (absolute error
/// about 1e-6 in `f32`) and returns the log-likelihood `ln S(α)`. Two passes over the
/// components (values, then posteriors); [`State`] keeps the posteriors instead.
pub fn marginals(e: &Evidence, out: &mut Marginals) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    marginals_unchecked(e, out)
}}

/// Like [`mpe`], without validating the evidence.
pub fn mpe_unchecked(e: &Evidence, labels: &mut Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    let acc = values(e, &ALL_UNKNOWN, true);
    let (Some(d), scale) = ({P}best(&acc), {P}log_scale(e, &ALL_UNKNOWN)) else {{
        return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
    }};
    let v = match acc.get(d) {{
        Some(a) => scale + a.ln() - {P}Real::ln(NUM_DECOMPOSITIONS as {t}),
        None => {t}::NEG_INFINITY,
    }};
    if !(v > {t}::NEG_INFINITY) {{
        return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
    }}
    {mpe_calls}
    Ok(v)
}}

/// Writes the max-product (MPE) labelling into `labels` and returns its natural-log
/// max-product value `max_d ln((1/D) Π_k maxprod T_k)`, ties broken towards the lowest
/// decomposition.
pub fn mpe(e: &Evidence, labels: &mut Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
    {P}check_{t}(e, &PLACE_IDS)?;
    mpe_unchecked(e, labels)
}}

/// Streaming inference for a robot that gets evidence one place at a time: the
/// caller-owned cache of every component's value and local posteriors (fixed size,
/// [`STATE_BYTES`] bytes, nothing on the heap; `const` constructor, so it can live in a
/// `static` or `.bss`).
///
/// An update (`set_evidence`, `observe`, `clear_evidence`) re-evaluates only the
/// components containing that place (at most one per decomposition) and re-mixes the
/// decompositions from the cached component values (never by subtracting, so
/// thousands of updates do not drift). Costs: an update, about
/// [`MACS_OBSERVE_MARGINALS`] multiply-adds with `marginals`; `log_likelihood` and
/// `marginal` O(1) and O(D·C); `marginals` O(components·places·C); `mpe` and
/// `labelled_log_likelihood` a full stateless pass on the state's evidence. The first
/// call after [`State::new`] evaluates every component once. [`State::new`] is all
/// zeros, so a `static` state is placed in `.bss` (no initial image in flash).
/// No evidence at a place means a row of ones.
#[derive(Clone)]
pub struct State {{
    ev: Evidence,
    lns: [{t}; NUM_PLACES],
    val: [{t}; NUM_COMPONENTS],
    post: [[{t}; NUM_CLASSES]; NUM_ROWS],
    w: [{t}; NUM_DECOMPOSITIONS],
    lhat: {t},
    ok: bool,
    ready: bool,
}}

/// The rows of a state without any evidence.
const NO_EVIDENCE: Evidence = [[1.0; NUM_CLASSES]; NUM_PLACES];

impl Default for State {{
    fn default() -> Self {{
        Self::new()
    }}
}}

impl State {{
    /// A state with no evidence at any place (all zeros in memory: rows of ones are
    /// written by the first call that needs them).
    pub const fn new() -> State {{
        State {{
            ev: [[0.0; NUM_CLASSES]; NUM_PLACES],
            lns: [0.0; NUM_PLACES],
            val: [0.0; NUM_COMPONENTS],
            post: [[0.0; NUM_CLASSES]; NUM_ROWS],
            w: [0.0; NUM_DECOMPOSITIONS],
            lhat: 0.0,
            ok: false,
            ready: false,
        }}
    }}

    /// The current evidence rows (all ones where a place has none).
    pub fn evidence(&self) -> &Evidence {{
        if self.ready {{ &self.ev }} else {{ &NO_EVIDENCE }}
    }}

    {eval_fns}

    fn eval_unit(&mut self, unit: usize) {{
        {dispatch}
    }}

    /// Re-mixes the decompositions from the cached component values.
    fn remix(&mut self) {{
        let mut acc = [{P}Acc::ONE; NUM_DECOMPOSITIONS];
        {state_value_calls}
        match {P}mix(&acc) {{
            Some((l, w)) => {{
                self.lhat = l;
                self.w = w;
                self.ok = true;
            }}
            None => self.ok = false,
        }}
    }}

    /// Evaluates every component (after `set_all`, or on the first use of a new state).
    fn refresh(&mut self) {{
        {refresh_calls}
        self.remix();
        self.ready = true;
    }}

    /// A new state gets its rows of ones and every component evaluated.
    fn fresh(&mut self) {{
        if !self.ready {{
            self.ev = NO_EVIDENCE;
            self.lns = [0.0; NUM_PLACES];
            self.refresh();
        }}
    }}

    /// Stores `row` for `place` and re-evaluates the components containing it.
    fn store(&mut self, place: usize, row: [{t}; NUM_CLASSES], ln_scale: {t}) {{
        self.fresh();
        if let (Some(r), Some(s)) = (self.ev.get_mut(place), self.lns.get_mut(place)) {{
            *r = row;
            *s = ln_scale;
        }}
        if let Some(units) = PLACE_UNITS.get(place) {{
            for &u in units {{
                self.eval_unit(u as usize);
            }}
        }}
        self.remix();
    }}

    fn place_index(place: usize) -> Result<u32, ::graphspn_runtime::EvidenceError> {{
        PLACE_IDS.get(place).copied().ok_or(::graphspn_runtime::EvidenceError::WrongShape {{ place, expected: NUM_PLACES, found: place }})
    }}

    /// Sets the evidence row of `place` (place index) and updates the cache. An invalid
    /// row (NaN, infinite, negative, all zero) is rejected and nothing changes.
    pub fn set_evidence(&mut self, place: usize, row: &[{t}; NUM_CLASSES]) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        let id = Self::place_index(place)?;
        {P}check_row(row, place, id)?;
        let s = row.iter().copied().fold(0.0, {t}::max);
        self.store(place, *row, {P}Real::ln(s));
        Ok(())
    }}

    /// Fuses a new observation into the place's row (element-wise product, renormalised
    /// to a largest entry of 1, so repeated observations never underflow) and updates
    /// the cache. An invalid row, or one that leaves the place no class at all, is
    /// rejected and nothing changes.
    pub fn observe(&mut self, place: usize, row: &[{t}; NUM_CLASSES]) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        let id = Self::place_index(place)?;
        {P}check_row(row, place, id)?;
        self.fresh();
        let old = match self.ev.get(place) {{
            Some(r) => *r,
            None => [1.0; NUM_CLASSES],
        }};
        match {P}fuse_rows(&old, row) {{
            Some(f) => {{
                self.store(place, f, 0.0);
                Ok(())
            }}
            None => Err(::graphspn_runtime::EvidenceError::NoMass {{ place, place_id: u64::from(id) }}),
        }}
    }}

    /// Removes the evidence of `place` (back to a row of ones) and updates the cache.
    pub fn clear_evidence(&mut self, place: usize) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        Self::place_index(place)?;
        self.store(place, [1.0; NUM_CLASSES], 0.0);
        Ok(())
    }}

    /// Replaces all evidence and re-evaluates every component.
    pub fn set_all(&mut self, e: &Evidence) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        {P}check_{t}(e, &PLACE_IDS)?;
        self.ev = *e;
        for (s, row) in self.lns.iter_mut().zip(e) {{
            *s = {P}Real::ln(row.iter().copied().fold(0.0, {t}::max));
        }}
        self.refresh();
        Ok(())
    }}

    /// Natural log of the likelihood of the current evidence (from the cache).
    pub fn log_likelihood(&mut self) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        self.fresh();
        let scale: {t} = self.lns.iter().copied().sum();
        if self.ok && scale + self.lhat > {t}::NEG_INFINITY {{
            Ok(scale + self.lhat)
        }} else {{
            Err(::graphspn_runtime::EvidenceError::ZeroLikelihood)
        }}
    }}

    /// Writes the marginals of every place into `out` from the cache and returns the
    /// log-likelihood.
    pub fn marginals(&mut self, out: &mut Marginals) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        let l = self.log_likelihood()?;
        for row in out.iter_mut() {{
            *row = [0.0; NUM_CLASSES];
        }}
        {state_marginal_calls}
        Ok(l)
    }}

    /// Writes the marginal of one place into `row` (O(D·C) from the cache).
    pub fn marginal(&mut self, place: usize, row: &mut [{t}; NUM_CLASSES]) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        Self::place_index(place)?;
        self.log_likelihood()?;
        if let Some(slots) = PLACE_SLOTS.get(place) {{
            {P}mix_rows(&self.post, slots, &self.w, row);
        }}
        Ok(())
    }}

    /// The MPE labelling of the current evidence (a full max-product pass).
    pub fn mpe(&mut self, labels: &mut Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        mpe_unchecked(self.evidence(), labels)
    }}

    /// The log-likelihood of the current evidence with labelled places restricted to
    /// their labels (a full value pass).
    pub fn labelled_log_likelihood(&mut self, labels: &Labels) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        {P}check_labels(labels, NUM_CLASSES)?;
        labelled_log_likelihood_unchecked(labels, self.evidence())
    }}
}}

/// This map as a [`::graphspn_runtime::CompiledMap`], for code generic over compiled maps.
pub struct Map;

impl ::graphspn_runtime::CompiledMap for Map {{
    type Scalar = {t};
    type Row = [{t}; NUM_CLASSES];
    type State = State;
    const NUM_PLACES: usize = NUM_PLACES;
    const NUM_CLASSES: usize = NUM_CLASSES;
    const NUM_DECOMPOSITIONS: usize = NUM_DECOMPOSITIONS;
    const PLACE_IDS: &'static [u32] = &PLACE_IDS;
    const CLASS_NAMES: &'static [&'static str] = &CLASS_NAMES;
    const ZERO_ROW: Self::Row = [0.0; NUM_CLASSES];
    const NEW_STATE: State = State::new();
    const LANES: usize = LANES;
    const NUM_COMPONENTS: usize = NUM_COMPONENTS;
    const STACK_BYTES_LOG_LIKELIHOOD: usize = STACK_BYTES_LOG_LIKELIHOOD;
    const STACK_BYTES_MARGINALS: usize = STACK_BYTES_MARGINALS;
    const STACK_BYTES_MPE: usize = STACK_BYTES_MPE;
    const STACK_BYTES_STATE: usize = STACK_BYTES_STATE;
    const STATE_BYTES: usize = STATE_BYTES;
    const MACS_LOG_LIKELIHOOD: usize = MACS_LOG_LIKELIHOOD;
    const MACS_MARGINALS: usize = MACS_MARGINALS;
    const MACS_MPE: usize = MACS_MPE;
    const MACS_OBSERVE_MARGINALS: usize = MACS_OBSERVE_MARGINALS;
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
    fn set_evidence(s: &mut State, place: usize, row: &Self::Row) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        s.set_evidence(place, row)
    }}
    fn observe(s: &mut State, place: usize, row: &Self::Row) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        s.observe(place, row)
    }}
    fn clear_evidence(s: &mut State, place: usize) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        s.clear_evidence(place)
    }}
    fn state_log_likelihood(s: &mut State) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        s.log_likelihood()
    }}
    fn state_marginals(s: &mut State, out: &mut [Self::Row]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        s.marginals({P}fixed_mut(out)?)
    }}
    fn state_marginal(s: &mut State, place: usize, row: &mut Self::Row) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        s.marginal(place, row)
    }}
    fn state_evidence(s: &State) -> &[Self::Row] {{
        s.evidence()
    }}
    fn set_all(s: &mut State, e: &[Self::Row]) -> Result<(), ::graphspn_runtime::EvidenceError> {{
        s.set_all({P}fixed(e)?)
    }}
    fn state_labelled_log_likelihood(s: &mut State, labels: &[u16]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        s.labelled_log_likelihood({P}fixed(labels)?)
    }}
    fn state_mpe(s: &mut State, labels: &mut [u16]) -> Result<{t}, ::graphspn_runtime::EvidenceError> {{
        s.mpe({P}fixed_mut(labels)?)
    }}
}}
"#,
        sl = report.stack_log_likelihood,
        sm = report.stack_marginals,
        sp = report.stack_mpe,
        ss = report.stack_state,
        ml = report.macs_log_likelihood,
        mm = report.macs_marginals,
        mp = report.macs_mpe,
        mo = report.macs_observe_marginals,
        ids = ids.join(", "),
        names = names.join(", ")
    );
    Ok((s, report))
}
