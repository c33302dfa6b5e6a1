//! The per-map part of the generated module: constants, the component tables of
//! every template, the public stateless API and the streaming `State` type.
//!
//! # Shape
//!
//! Components are deduplicated across decompositions (same template and places) and
//! listed template by template in `static` tables: each template's components in
//! groups of `L` (one per lane of the module's vector type `V`: `L = 1` on targets
//! without float SIMD, 8 (`f32`) or 4 (`f64`) on the host; the last group padded with
//! its first member), and per component the bit set of decompositions containing it.
//! The generic driver `graphspn_runtime::__private::engine` runs over those tables and
//! calls the template's straight-line functions (`sparse/`, or `template.rs` for
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
//! - `State`: the caller owns per component its value and local posteriors, so an
//!   update of one place re-evaluates only the groups containing it.
//!
//! # Where each part is emitted
//!
//! [`module`] decides the per-template evaluation plan once ([`plan_templates`]: block
//! or per-node code, lanes, numerics, multiply-adds, stack frame) and numbers the
//! components, posterior rows and lane groups ([`Layout`]); every pass reads those.
//! Constants, types and tables are emitted here; the value pass, posterior pass, MPE
//! and the rest of the stateless API in `api.rs`; the streaming state in `state.rs`.

mod api;
mod state;

use proc_macro2::{Ident, TokenStream};
use quote::{ToTokens, format_ident, quote};

use crate::decompose::Decomposition;
use crate::learn::Model;
use crate::map::TopoMap;

use super::analysis::{Numerics, Unique, numerics, unique_components};
use super::emit::{Lit, array, hex, int, int_array, rt};
use super::sparse::{Counts, SparseCode};
use super::surface::{CodeReport, Surface, compiled_map_impl, constants_and_types, fused_bytes};
use super::template::TemplateCode;
use super::{Arithmetic, CodegenError, CodegenOptions, Precision, Vectorisation};
use super::{fixed, kernels};

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

/// What every emitter of the per-map part needs: sizes, scalar type, lanes.
struct Context {
    /// Scalar type and literals.
    l: Lit,
    /// Places.
    n: usize,
    /// Classes.
    c: usize,
    /// Decompositions.
    d_count: usize,
    /// Bytes of one scalar.
    scalar: usize,
    /// Lanes of block templates (`1`: scalar code).
    simd_lanes: usize,
    /// Fixed-point value and posterior functions for block templates.
    fixed: bool,
    /// Components of the largest decomposition (the `K` of the fixed-point bound).
    k_max: usize,
}

impl Context {
    fn new(
        map: &TopoMap,
        model: &Model,
        decs: &[Decomposition],
        options: &CodegenOptions,
    ) -> Result<Context, CodegenError> {
        let n = map.num_places();
        let d_count = decs.len();
        options.check(n)?;
        let fixed = options.arithmetic == Arithmetic::Fixed;
        if d_count > super::MAX_COMPILED_DECOMPOSITIONS {
            return Err(CodegenError::BadOption(format!(
                "at most {} decompositions can be compiled, got {d_count}",
                super::MAX_COMPILED_DECOMPOSITIONS
            )));
        }
        Ok(Context {
            l: Lit::new(options.precision),
            n,
            c: model.classes.len(),
            d_count,
            scalar: match options.precision {
                Precision::F32 => 4,
                Precision::F64 => 8,
            },
            simd_lanes: match (options.vectorisation, options.precision) {
                (Vectorisation::Scalar, _) => 1,
                (Vectorisation::Simd, Precision::F32) => 8,
                (Vectorisation::Simd, Precision::F64) => 4,
            },
            fixed,
            k_max: decs.iter().map(|d| d.components.len()).max().unwrap_or(0),
        })
    }
}

/// One template's evaluation plan, shared by every pass: its functions, lanes,
/// numerics, counts, stack frame, components and where they sit in the tables.
struct Tpl {
    prefix: String,
    /// Name of its `static` driver table (`T0_STAR`).
    stat: Ident,
    /// Components per call.
    lanes: usize,
    /// Block code (lane type `V`) or per-node code (the scalar type).
    blocks: bool,
    vars: usize,
    numerics: Numerics,
    counts: Counts,
    /// Extra stack of its functions beyond the arrays the driver holds (bytes).
    frame: usize,
    /// Indices into the unique components, in order.
    members: Vec<usize>,
    /// Its template functions.
    code: TokenStream,
    /// Index of its first component among all components.
    first_component: usize,
    /// Index of its first posterior row.
    first_row: usize,
}

impl Tpl {
    fn groups(&self) -> usize {
        self.members.len().div_ceil(self.lanes)
    }

    /// Its `eval_group_<i>` method of the state.
    fn eval_group(&self, ti: usize) -> Ident {
        format_ident!("eval_group_{ti}")
    }
}

/// Decides how each template with components in the map is evaluated (floor +
/// sparse block code in lane groups when its SPN has block structure and linear
/// numerics, per-node scalar code otherwise), emits its functions, and numbers its
/// components and rows.
fn plan_templates(model: &Model, uniques: &[Unique], cx: &Context) -> Vec<Tpl> {
    let mut tpls: Vec<Tpl> = Vec::new();
    let (mut components, mut rows) = (0, 0);
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
        // lint: the prefix of the template's identifiers (format_ident! at each use)
        let prefix = format!("t{k}_{}", sanitize(&model.templates[k].name));
        let plan = kernels::plan(spn, cx.c);
        let num = numerics(spn, cx.l.precision(), plan.as_ref());
        let vars = spn.num_vars();
        let mut tpl = Tpl {
            stat: format_ident!("{}", prefix.to_uppercase()),
            prefix,
            lanes: 1,
            blocks: false,
            vars,
            numerics: num,
            counts: Counts::default(),
            frame: 0,
            members,
            code: TokenStream::new(),
            first_component: components,
            first_row: rows,
        };
        match (&plan, num) {
            (Some(plan), Numerics::Linear { .. }) => block_code(&mut tpl, plan, cx),
            _ => per_node_code(&mut tpl, spn, cx),
        }
        components += tpl.members.len();
        rows += tpl.members.len() * tpl.vars;
        tpls.push(tpl);
    }
    tpls
}

/// Floor + sparse block functions in lane groups (`sparse/`).
fn block_code(tpl: &mut Tpl, plan: &kernels::Plan, cx: &Context) {
    let code = SparseCode::float(tpl.prefix.clone(), plan);
    let mut ops = |(tokens, ops): (TokenStream, usize)| {
        tpl.code.extend(tokens);
        ops
    };
    let (fwd, post) = if cx.fixed {
        fixed_code(&tpl.prefix, plan, cx, &mut ops)
    } else {
        (ops(code.fwd(&cx.l)), ops(code.post(&cx.l)))
    };
    let counts = Counts {
        fwd,
        post,
        max: ops(code.max(&cx.l)),
        mpe: ops(code.mpe(&cx.l, cx.simd_lanes)),
    };
    let sums: usize = plan.blocks.iter().map(|b| b.sums.len()).sum();
    // Block values and adjoints, variable adjoints, MPE arguments and selections, and
    // room for spills of the straight-line temporaries (Cortex-M4F, 230-place map:
    // the Star's posterior function has a 2.2 KB frame, a whole `mpe` call 1.6 KB); the
    // fixed-point wrappers' Q0.32 rows and adjoints.
    let wrapper = if cx.fixed { 2 * tpl.vars * cx.c * 4 } else { 0 };
    tpl.frame =
        (2 * sums + tpl.vars * cx.c) * cx.simd_lanes * cx.scalar + 10 * sums + 4096 + wrapper;
    tpl.counts = counts;
    tpl.lanes = cx.simd_lanes;
    tpl.blocks = true;
}

/// The fixed-point kernel of a block template (see `codegen::fixed`): the `f32`
/// functions as `<t>_fl_fwd` / `<t>_fl_post`, their Q0.32 twins `<t>_fx_*`, and the
/// `<t>_fwd` / `<t>_post` the driver calls, which keep a fixed-point result above the
/// function's threshold. Returns the fixed-point functions' multiply counts.
fn fixed_code(
    prefix: &str,
    plan: &kernels::Plan,
    cx: &Context,
    ops: &mut impl FnMut((TokenStream, usize)) -> usize,
) -> (usize, usize) {
    let rt = rt();
    // lint: the prefix of the f32 functions' identifiers (format_ident! at each use)
    let float = SparseCode::float(format!("{prefix}_fl"), plan);
    // lint: the prefix of the fixed-point twins' identifiers
    let fx = SparseCode::fixed(format!("{prefix}_fx"), plan);
    ops(float.fwd(&cx.l));
    ops(float.post(&cx.l));
    // The value: its forward sweep's units, each rounding weighted by its sensitivity.
    let fwd = ops(fx.fwd(&cx.l));
    fx.take_shift_units();
    let fwd_units = fx.forward_units().ceil() as u64;
    // The posteriors: the forward sweep's units plus every backward rounding at its
    // scale (an adjoint's error reaches a posterior with a factor at most 1).
    let post = ops(fx.post(&cx.l));
    let backward = fx.backward_units().ceil() as u64 + fx.take_shift_units() as u64;
    let post_units = fwd_units + backward;
    let (min_fwd, min_post) = fixed::thresholds(fwd_units, post_units);
    let id = |s: &str| format_ident!("{prefix}_{s}");
    let (w_fwd, fl_fwd, fx_fwd) = (id("fwd"), id("fl_fwd"), id("fx_fwd"));
    let (w_post, fl_post, fx_post) = (id("post"), id("fl_post"), id("fx_post"));
    let (c, n) = (int(plan.classes), int(plan.n));
    ops((
        quote!(
            #[inline(never)]
            fn #w_fwd(x: &[[V; #c]; #n]) -> V {
                #rt::fx_fwd(x, #min_fwd, #fx_fwd, #fl_fwd)
            }
            #[inline(never)]
            fn #w_post(x: &[[V; #c]; #n], post: &mut [[V; #c]; #n]) -> V {
                #rt::fx_post(x, post, #min_post, #fx_post, #fl_post)
            }
        ),
        0,
    ));
    (fwd, post)
}

/// Per-node scalar functions (`template.rs`).
fn per_node_code(tpl: &mut Tpl, spn: &crate::spn::Spn, cx: &Context) {
    let code = TemplateCode {
        prefix: tpl.prefix.clone(),
        spn,
        numerics: tpl.numerics,
        classes: cx.c,
    };
    for tokens in [
        code.statics(&cx.l),
        code.fwd(&cx.l),
        code.post(&cx.l),
        code.mpe(&cx.l),
        code.max(&cx.l),
    ] {
        tpl.code.extend(tokens);
    }
    let edges: usize = spn
        .nodes
        .iter()
        .map(|nd| match nd {
            crate::spn::Node::Sum { children, .. } | crate::spn::Node::Product { children } => {
                children.len()
            }
            crate::spn::Node::Leaf { .. } => 0,
        })
        .sum();
    tpl.counts = Counts {
        fwd: edges,
        post: 3 * edges,
        max: edges,
        mpe: edges,
    };
    // One value per node (and one adjoint), plus spills.
    tpl.frame = 2 * spn.nodes.len() * cx.scalar + 2048;
}

/// Where every component's values sit for the state: totals and, per place, the
/// groups containing it and its posterior row in each decomposition.
struct Layout {
    /// Distinct components.
    components: usize,
    /// Posterior rows (one per component and variable).
    rows: usize,
    /// Per place: the components containing it (global indices, ascending, so each
    /// template's are adjacent).
    place_components: Vec<Vec<usize>>,
    /// Per place and decomposition: the place's posterior row.
    place_slots: Vec<Vec<u32>>,
}

impl Layout {
    fn new(tpls: &[Tpl], uniques: &[Unique], cx: &Context) -> Layout {
        let mut place_components: Vec<Vec<usize>> = vec![Vec::new(); cx.n];
        let mut place_slots: Vec<Vec<u32>> = vec![vec![u32::MAX; cx.d_count]; cx.n];
        // Each component's template and position in it.
        let mut position = vec![None; uniques.len()];
        for tp in tpls {
            for (i, &u) in tp.members.iter().enumerate() {
                position[u] = Some((tp, i));
            }
        }
        for (un, pos) in uniques.iter().zip(position) {
            let Some((tp, i)) = pos else { continue };
            for (v, &p) in un.places.iter().enumerate() {
                place_components[p].push(tp.first_component + i);
                let row = (tp.first_row + i * tp.vars + v) as u32;
                for &d in &un.decs {
                    place_slots[p][d] = row;
                }
            }
        }
        for comps in &mut place_components {
            comps.sort_unstable();
        }
        Layout {
            components: tpls.iter().map(|tp| tp.members.len()).sum(),
            rows: tpls.iter().map(|tp| tp.members.len() * tp.vars).sum(),
            place_components,
            place_slots,
        }
    }

    /// Longest list of components of one place (the width of `PLACE_COMPONENTS`).
    fn max_components(&self) -> usize {
        self.place_components
            .iter()
            .map(Vec::len)
            .max()
            .unwrap_or(0)
            .max(1)
    }

    /// Per place, the lane groups an update evaluates: per template, its components
    /// containing the place, `lanes` at a time (`(template, calls)`).
    fn update_batches<'t>(&self, tpls: &'t [Tpl], place: usize) -> Vec<(&'t Tpl, usize)> {
        tpls.iter()
            .filter_map(|tp| {
                let range = tp.first_component..tp.first_component + tp.members.len();
                let k = self.place_components[place]
                    .iter()
                    .filter(|c| range.contains(c))
                    .count();
                (k > 0).then(|| (tp, k.div_ceil(tp.lanes.max(1))))
            })
            .collect()
    }
}

/// The whole module as tokens, and its report.
pub fn module(
    model: &Model,
    map: &TopoMap,
    decs: &[Decomposition],
    options: &CodegenOptions,
) -> Result<(TokenStream, CodeReport), CodegenError> {
    let cx = Context::new(map, model, decs, options)?;
    let uniques = unique_components(decs);
    let tpls = plan_templates(model, &uniques, &cx);
    let layout = Layout::new(&tpls, &uniques, &cx);
    let (tables, table_bytes) = tables(&tpls, &uniques, &layout, &cx);
    let (report, passes) = report(&tpls, &layout, table_bytes, &cx, options)?;
    let lane_items = lane_items(&tpls, &cx);
    let constants = constants_and_types(&Surface {
        l: &cx.l,
        family: "graphspn",
        n: cx.n,
        c: cx.c,
        mixture: cx.d_count,
        mixture_doc: " Number of decompositions mixed (with uniform weights) at the root.",
        lanes: cx.simd_lanes,
        components: layout.components,
        report: &report,
        place_ids: map.places().map(|p| p.id).collect(),
        class_names: model.classes.names(),
        evidence_exponent: 1,
    });
    // The component cache's rows: the scalar state's and the one-pass marginals'.
    let num_rows = if cx.simd_lanes == 1 || passes.one_pass {
        let rows = int(layout.rows);
        quote!(const NUM_ROWS: usize = #rows;)
    } else {
        TokenStream::new()
    };
    let functions = tpls.iter().map(|tp| &tp.code);
    let value_pass = api::value_pass(&tpls, &cx);
    let stateless = api::stateless_api(&tpls, &cx, passes.one_pass, passes.prescale);
    let state = state::state_api(&tpls, &cx);
    let compiled_map = compiled_map_impl(&cx.l);
    let tokens = quote! {
        #lane_items
        #constants
        static ALL_UNKNOWN: Labels = [UNKNOWN; NUM_PLACES];
        #num_rows
        #(#functions)*
        #tables
        #value_pass
        #stateless
        #state
        #compiled_map
    };
    Ok((tokens, report))
}

/// The lane vector `V` of block templates (nothing when every template has
/// per-node code).
fn lane_items(tpls: &[Tpl], cx: &Context) -> TokenStream {
    if !tpls.iter().any(|tp| tp.blocks) {
        return TokenStream::new();
    }
    let rt = rt();
    let v_type = lane_vector(cx);
    quote! {
        use #rt::Lanes;
        /// The lane vector of block templates.
        type V = #v_type;
    }
}

/// The lane vector type of SIMD code (the scalar type without SIMD).
fn lane_vector(cx: &Context) -> TokenStream {
    let rt = rt();
    let t = cx.l.ty();
    match (cx.simd_lanes, cx.l.is_f32()) {
        (1, _) => quote!(#t),
        (_, true) => quote!(#rt::Lanes32),
        (_, false) => quote!(#rt::Lanes64),
    }
}

/// The `static` tables: per template the places of every lane group, the
/// decompositions of every component and the driver's `Tpl`; per place its groups
/// and posterior rows. Also their size in bytes.
fn tables(tpls: &[Tpl], uniques: &[Unique], layout: &Layout, cx: &Context) -> (TokenStream, usize) {
    let rt = rt();
    let mut out = TokenStream::new();
    let mut bytes = 0;
    for tp in tpls {
        let (name, lanes, v, c) = (&tp.stat, tp.lanes, int(tp.vars), int(cx.c));
        let places = format_ident!("{}_PLACES", name);
        let decs = format_ident!("{}_DECS", name);
        let groups = (0..tp.groups()).map(|g| {
            array((0..lanes).map(|ln| {
                let u = tp
                    .members
                    .get(g * lanes + ln)
                    .unwrap_or(&tp.members[g * lanes]);
                int_array(uniques[*u].places.iter().copied())
            }))
        });
        let groups = array(groups);
        let masks = array(
            tp.members
                .iter()
                .map(|&u| hex(uniques[u].decs.iter().map(|&d| 1u64 << d).sum())),
        );
        bytes += tp.groups() * lanes * tp.vars * 2 + tp.members.len() * 8;
        let (g, m) = (int(tp.groups()), int(tp.members.len()));
        let w = if tp.blocks {
            quote!(V)
        } else {
            cx.l.ty().clone().into_token_stream()
        };
        let log = matches!(tp.numerics, Numerics::Log);
        let lanes = int(lanes);
        let [fwd, post, max, mpe] =
            ["fwd", "post", "max", "mpe"].map(|f| format_ident!("{}_{}", tp.prefix, f));
        out.extend(quote! {
            static #places: [[[u16; #v]; #lanes]; #g] = #groups;
            static #decs: [u64; #m] = #masks;
            static #name: #rt::Tpl<#w, #lanes, #v, #c> = #rt::Tpl { places: &#places, decs: &#decs, log: #log, fwd: #fwd, post: #post, max: #max, mpe: #mpe };
        });
    }
    let max_comps = layout.max_components();
    let (comp_t, comp_bytes) = component_int(layout.components);
    let comps = array(layout.place_components.iter().map(|cs| {
        let mut v: Vec<TokenStream> = cs.iter().map(|&u| int(u).into_token_stream()).collect();
        v.resize(max_comps, quote!(#comp_t::MAX));
        array(v)
    }));
    bytes += cx.n * max_comps * comp_bytes;
    let max_comps = int(max_comps);
    out.extend(quote! {
        /// Per place: the components containing it, ascending (`MAX`: none).
        static PLACE_COMPONENTS: [[#comp_t; #max_comps]; NUM_PLACES] = #comps;
    });
    // Scalar code's state mixes a place's rows through the component cache; SIMD
    // hosts' state keeps the rows per decomposition instead (see `state.rs`).
    if cx.simd_lanes == 1 {
        let slots = array(
            layout
                .place_slots
                .iter()
                .map(|ss| array(ss.iter().map(|&s| proc_macro2::Literal::u32_unsuffixed(s)))),
        );
        bytes += cx.n * cx.d_count * 4;
        out.extend(quote! {
            /// Per place and decomposition: the place's row in the state's posteriors.
            static PLACE_SLOTS: [[u32; NUM_DECOMPOSITIONS]; NUM_PLACES] = #slots;
        });
    }
    (out, bytes)
}

/// The integer type of global component indices in `PLACE_COMPONENTS` (`MAX` is
/// padding) and its size in bytes.
fn component_int(components: usize) -> (Ident, usize) {
    if components < usize::from(u16::MAX) {
        (format_ident!("u16"), 2)
    } else {
        (format_ident!("u32"), 4)
    }
}

/// Bytes of the streaming `State` (`size_of`, exactly): the evidence rows (on SIMD hosts
/// also scaled, see `state.rs`), their scales, fused form and the sum of their shifts,
/// every component's value, the posterior rows (per component, or on SIMD hosts per
/// place and decomposition), the values' partial products, the decomposition weights,
/// the last likelihood and two flags.
fn state_bytes(layout: &Layout, tpls: &[Tpl], cx: &Context) -> usize {
    let (n, c, scalar) = (cx.n, cx.c, cx.scalar);
    // `Acc`: a mantissa, an `i32` exponent and a log, aligned to the scalar.
    let acc = 2 * scalar + scalar.max(4);
    let chunks = tpls.iter().map(state::value_chunks).sum::<usize>().max(1);
    let row_tables = if cx.simd_lanes > 1 { 2 } else { 1 };
    // The components' posterior rows: the component cache in scalar code, every
    // place's row per decomposition on SIMD hosts.
    let post_rows = if cx.simd_lanes > 1 {
        cx.d_count * n
    } else {
        layout.rows
    };
    // The fields, then `lhat` and the two flags; no field's size leaves a gap before a
    // field of smaller alignment, so only the end is padded, to the `i64`'s 8 bytes.
    let fields = n * c * scalar * row_tables
        + n * scalar
        + n * fused_bytes(c, scalar)
        + 8
        + layout.components * scalar
        + chunks * cx.d_count * acc
        + post_rows * c * scalar
        + cx.d_count * scalar
        + scalar
        + 2;
    let align = scalar.max(8);
    fields.div_ceil(align) * align
}

/// How the stateless entry points run (see [`api::stateless_api`]).
struct Passes {
    /// `marginals` evaluates every component once, keeping values and posteriors on
    /// the stack.
    one_pass: bool,
    /// Which entry points scale the evidence rows once into a stack table.
    prescale: Prescale,
}

/// Which entry points scale every evidence row once per call (see [`api::Table`]).
#[derive(Clone, Copy)]
pub(super) struct Prescale {
    /// The value passes: (labelled) log-likelihood and MPE.
    pub values: bool,
    /// `marginals` (both passes).
    pub marginals: bool,
}

/// Stack bounds, state and table bytes and multiply-adds of the generated code, and
/// how the stateless entry points run ([`Passes`]); fails when a stack bound exceeds
/// the budget.
fn report(
    tpls: &[Tpl],
    layout: &Layout,
    table_bytes: usize,
    cx: &Context,
    options: &CodegenOptions,
) -> Result<(CodeReport, Passes), CodegenError> {
    let (n, c, d_count, scalar) = (cx.n, cx.c, cx.d_count, cx.scalar);
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
    let (u_total, rows) = (layout.components, layout.rows);
    let per_groups =
        |f: &dyn Fn(&Tpl) -> usize| -> usize { tpls.iter().map(|tp| tp.groups() * f(tp)).sum() };
    let macs_ll = per_groups(&|tp| tp.counts.fwd);
    // Marginals in one pass (SIMD code whose scratch of every component's value and
    // posteriors fits the budget): `_post` only; otherwise a value pass first.
    let two_pass_stack = top
        + d_count * scalar
        + deepest
        + tpls
            .iter()
            .map(|tp| tp.vars * c * tp.lanes * scalar)
            .max()
            .unwrap_or(0);
    // SIMD hosts scale every evidence row once per call, into `n × c` scalars on the
    // stack where that fits the budget (first the one-pass marginals' scratch, then the
    // table), or for one-pass marginals into the caller's output.
    let budget = options.stack_budget();
    let scaled = n * c * scalar;
    let scratch = (u_total + rows * c) * scalar;
    let one_pass = cx.simd_lanes > 1 && two_pass_stack + scratch <= budget;
    let marginals_stack = two_pass_stack + if one_pass { scratch } else { 0 };
    let prescale = Prescale {
        values: cx.simd_lanes > 1 && top + deepest + scaled <= budget,
        marginals: cx.simd_lanes > 1 && (one_pass || marginals_stack + scaled <= budget),
    };
    let with_table = |yes: bool, stack: usize| stack + if yes { scaled } else { 0 };
    let macs_post = per_groups(&|tp| tp.counts.post) + rows * c;
    let macs_marg = if one_pass {
        macs_post
    } else {
        macs_ll + macs_post
    };
    let macs_mpe = per_groups(&|tp| tp.counts.max)
        + tpls
            .iter()
            .map(|tp| {
                tp.members
                    .len()
                    .div_ceil(d_count.max(1))
                    .div_ceil(tp.lanes.max(1))
                    * tp.counts.mpe
            })
            .sum::<usize>();
    let update_cost = |place: usize| -> (usize, usize) {
        let batches = layout.update_batches(tpls, place);
        let macs = batches.iter().map(|(tp, k)| k * tp.counts.post).sum();
        (macs, batches.iter().map(|(_, k)| k).sum())
    };
    let worst_update = (0..n).map(|p| update_cost(p).0).max().unwrap_or(0);
    let mut report = CodeReport {
        lanes: cx.simd_lanes,
        components: u_total,
        stack_log_likelihood: with_table(prescale.values, top + deepest),
        stack_marginals: with_table(prescale.marginals && !one_pass, marginals_stack),
        stack_mpe: with_table(prescale.values, top + deepest),
        stack_state: 0,
        state_bytes: state_bytes(layout, tpls, cx),
        table_bytes,
        macs_log_likelihood: macs_ll,
        macs_marginals: macs_marg,
        macs_mpe,
        macs_observe_marginals: worst_update + u_total * 2 + rows * c,
        units_per_update: (0..n).map(|p| update_cost(p).1).sum::<usize>() as f64 / n.max(1) as f64,
        message_error: None,
    };
    report.stack_state = report.state_bound(top + deepest);
    report.check_budget(options)?;
    Ok((report, Passes { one_pass, prescale }))
}
