//! The stateless API of the generated module: the value pass, the posterior pass
//! (`marginals`), MPE, the (labelled) log-likelihood and the `CompiledMap` impl.

use proc_macro2::TokenStream;
use quote::quote;

use super::super::emit::{int, rt};
use super::super::surface::{checked, checked_labelled};
use super::{Context, Prescale, Tpl, state};

/// One driver call per template, `call(table)` with the template's `static` table.
fn per_template(tpls: &[Tpl], call: impl Fn(&Tpl) -> TokenStream) -> TokenStream {
    tpls.iter().map(call).collect()
}

/// Where an entry point keeps the evidence rows scaled once per call (SIMD hosts:
/// gathers are then loads only; see the runtime's `scale_rows`).
#[derive(Clone, Copy)]
pub(super) enum Table {
    /// No table: each gather scales its rows (no scratch; microcontrollers).
    None,
    /// A table on the stack (`n × c` scalars).
    Stack,
    /// The caller's `out` (marginals in one pass: written only after the last gather).
    Out,
}

/// Binds `table`, the evidence rows scaled once per call that the passes read (`None`:
/// each gather scales its rows), as `kind` says (`labels`: an `Option<&Labels>`).
fn bind_table(kind: Table, labels: TokenStream) -> TokenStream {
    let rt = rt();
    match kind {
        Table::None => quote!(let table: Option<&Evidence> = None;),
        Table::Stack => quote! {
            let mut scaled = [[0.0; NUM_CLASSES]; NUM_PLACES];
            #rt::scale_rows(e, #labels, &mut scaled);
            let table = Some(&scaled);
        },
        Table::Out => quote! {
            #rt::scale_rows(e, #labels, out);
            let table = Some(&*out);
        },
    }
}

/// `values` (every component's value, or max-product value, into the decomposition
/// accumulators) and `finish` (`ln S` and the decomposition weights).
pub(super) fn value_pass(tpls: &[Tpl], cx: &Context) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let calls = per_template(tpls, |tp| {
        let stat = &tp.stat;
        quote!(#rt::value_pass(&#stat, e, labels, table, max, &mut acc);)
    });
    quote! {
        /// The decomposition accumulators of a value pass (`max`: max-product values;
        /// `table`: the rows scaled once, see `scale_rows`).
        fn values(e: &Evidence, labels: &Labels, table: Option<&Evidence>, max: bool) -> [#rt::Acc<#t>; NUM_DECOMPOSITIONS] {
            let mut acc = [#rt::Acc::ONE; NUM_DECOMPOSITIONS];
            #calls
            acc
        }

        /// `ln S` from the decomposition accumulators and the evidence scale.
        fn finish(acc: &[#rt::Acc<#t>; NUM_DECOMPOSITIONS], scale: #t) -> Result<(#t, [#t; NUM_DECOMPOSITIONS]), ::graphspn_runtime::EvidenceError> {
            match #rt::mix(acc) {
                Some((l, w)) if scale + l > #t::NEG_INFINITY => Ok((scale + l, w)),
                _ => Err(::graphspn_runtime::EvidenceError::ZeroLikelihood),
            }
        }
    }
}

/// The stateless entry points: (labelled) log-likelihood, marginals, MPE, each with
/// its `_unchecked` twin. `one_pass`: `marginals` evaluates every component once with
/// its posteriors, keeping them on the stack until the decomposition weights are known
/// (SIMD hosts); otherwise a value pass, then a posterior pass (microcontrollers: no
/// scratch of the size of the map).
///
/// `prescale`: which entry points scale every evidence row once (see [`Table`]).
pub(super) fn stateless_api(
    tpls: &[Tpl],
    cx: &Context,
    one_pass: bool,
    prescale: Prescale,
) -> TokenStream {
    let values = if prescale.values {
        Table::Stack
    } else {
        Table::None
    };
    let likelihood = likelihood_api(cx, values);
    let marginals = posterior_pass(tpls, cx, one_pass, prescale.marginals);
    let mpe = mpe(tpls, cx, values);
    quote!(#likelihood #marginals #mpe)
}

/// What the documentation of `log_likelihood` and `marginals` says of their error:
/// rounding in floating point, or the fixed-point kernel's bound with this module's
/// numbers (`K`, `D`; see the generator's `fixed` module and `Arithmetic::Fixed`).
struct Accuracy {
    /// The rest of `log_likelihood`'s first sentence.
    log_likelihood: String,
    /// The rest of `marginals`' first sentence.
    marginals: String,
}

impl Accuracy {
    fn of(cx: &Context) -> Accuracy {
        if !cx.fixed {
            return Accuracy {
                log_likelihood: " (relative error about 1e-6 in `f32`: one rounding per multiply-add, products kept with exact exponents).".into(),
                marginals: " (absolute error about 1e-6 in `f32`).".into(),
            };
        }
        let unit = 2f64.powi(-13);
        let (k, d) = (cx.k_max as f64, cx.d_count as f64);
        let ll = k * unit;
        let marginal = 8.0 * unit + 2.0 * k * unit + 3.0 * d * 2f64.powi(-31);
        // lint: the bound's numbers are this module's, part of a doc comment.
        let log_likelihood = format!(
            " (fixed-point kernel: block templates in Q0.32 integers, each kept value within `2^-13` of itself, so within `K·2^-13` = {ll:.1e} nats of exact arithmetic, `K` = {} components in the largest decomposition; a loose worst case, plus `f32` rounding).",
            cx.k_max
        );
        // lint: the bound's numbers are this module's, part of a doc comment.
        let marginals = format!(
            " (fixed-point kernel: each entry within `2^-10 + 2K·2^-13 + 3D·2^-31` = {marginal:.1e} of exact arithmetic, `K` = {} components in the largest decomposition, `D` = {} decompositions; a loose worst case).",
            cx.k_max, cx.d_count
        );
        Accuracy {
            log_likelihood,
            marginals,
        }
    }
}

/// `log_likelihood` and `labelled_log_likelihood` (value pass only).
fn likelihood_api(cx: &Context, table: Table) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let table = bind_table(table, quote!(Some(labels)));
    let accuracy = Accuracy::of(cx);
    let log_likelihood = checked(
        &cx.l,
        &[
            " Natural log of the likelihood `S(α)` of the evidence",
            &accuracy.log_likelihood,
        ],
        "log_likelihood",
        quote!(e: &Evidence),
        quote!(e),
        TokenStream::new(),
    );
    let labelled = checked_labelled(&cx.l);
    quote! {
        /// Natural log of the likelihood `S(α)` of the evidence, without validating it.
        /// Invalid evidence gives unspecified numbers (never a panic).
        pub fn log_likelihood_unchecked(e: &Evidence) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            labelled_log_likelihood_unchecked(&ALL_UNKNOWN, e)
        }

        #log_likelihood

        /// Like [`labelled_log_likelihood`], without validating evidence or labels.
        pub fn labelled_log_likelihood_unchecked(labels: &Labels, e: &Evidence) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            labelled_scaled(labels, e, #rt::log_scale(e, labels))
        }

        /// The labelled value pass with the log of the rows' scales given (`log_scale`;
        /// the streaming state gives its labels' exact fused values instead).
        #[inline(always)]
        fn labelled_scaled(labels: &Labels, e: &Evidence, scale: #t) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            #table
            let acc = values(e, labels, table, false);
            finish(&acc, scale).map(|(l, _)| l)
        }

        #labelled
    }
}

/// `marginals`: every component's weighted local posteriors, after a value pass (or,
/// `one_pass`, from one evaluation of every component kept on the stack).
fn posterior_pass(tpls: &[Tpl], cx: &Context, one_pass: bool, prescale: bool) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let table = match (prescale, one_pass) {
        (false, _) => Table::None,
        (true, true) => Table::Out,
        (true, false) => Table::Stack,
    };
    let table = bind_table(table, quote!(None));
    let passes = if one_pass {
        " One pass over the components (each evaluated once with its posteriors, kept on the"
    } else {
        " Two passes over the components (values, then posteriors); [`State`] keeps the"
    };
    let passes_end = if one_pass {
        " stack until the decompositions' weights are known)."
    } else {
        " posteriors instead."
    };
    let accuracy = Accuracy::of(cx);
    let checked = checked(
        &cx.l,
        &[
            " Writes the marginals `P(Y_p = c | α)` of every place into `out`",
            &accuracy.marginals,
            " Returns the log-likelihood `ln S(α)`.",
            passes,
            passes_end,
        ],
        "marginals",
        quote!(e: &Evidence, out: &mut Marginals),
        quote!(e, out),
        TokenStream::new(),
    );
    if one_pass {
        return one_pass_marginals(tpls, cx, checked, table);
    }
    // Without an FPU (the fixed-point kernel's targets) the weighted posteriors are
    // summed in Q1.31 integer multiply-adds, as the `State` mixes them: a soft-float
    // multiply and add per entry cost about 85 instructions.
    let (weights, pass, finish_rows) = if cx.fixed {
        (
            quote!(let wq = #rt::fx_weights(&w);),
            quote!(posterior_pass_fx),
            quote!(#rt::fx_finish_rows(out);),
        )
    } else {
        (
            TokenStream::new(),
            quote!(posterior_pass),
            TokenStream::new(),
        )
    };
    let wref = if cx.fixed { quote!(&wq) } else { quote!(&w) };
    let calls = per_template(tpls, |tp| {
        let stat = &tp.stat;
        quote!(#rt::#pass(&#stat, e, table, #wref, out);)
    });
    quote! {
        /// Like [`marginals`], without validating the evidence.
        pub fn marginals_unchecked(e: &Evidence, out: &mut Marginals) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            #table
            let acc = values(e, &ALL_UNKNOWN, table, false);
            let (l, w) = finish(&acc, #rt::log_scale(e, &ALL_UNKNOWN))?;
            #weights
            for row in out.iter_mut() {
                *row = [0.0; NUM_CLASSES];
            }
            #calls
            #finish_rows
            Ok(l)
        }

        #checked
    }
}

/// `marginals` in one pass: every lane group evaluated once with its posteriors
/// (values and posteriors stored as in the `State`'s cache), the decompositions
/// mixed from the values, then the weighted posteriors added up.
fn one_pass_marginals(
    tpls: &[Tpl],
    cx: &Context,
    checked: TokenStream,
    table: TokenStream,
) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let mut eval = TokenStream::new();
    for tp in tpls {
        let (stat, groups) = (&tp.stat, int(tp.groups()));
        let (first_component, first_row) = (int(tp.first_component), int(tp.first_row));
        eval.extend(quote! {
            if let (Some(v), Some(p)) = (val.get_mut(#first_component..), post.get_mut(#first_row..)) {
                for g in 0..#groups {
                    #rt::eval_group(&#stat, e, table, g, v, p);
                }
            }
        });
    }
    let values = state::cached_values(tpls, &quote!(val));
    let scatter = state::cached_marginals(tpls, &quote!(post), &quote!(w));
    quote! {
        /// Like [`marginals`], without validating the evidence.
        pub fn marginals_unchecked(e: &Evidence, out: &mut Marginals) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            #table
            let mut val = [0.0; NUM_COMPONENTS];
            let mut post = [[0.0; NUM_CLASSES]; NUM_ROWS];
            #eval
            // `out` may hold the scaled rows: cleared before any early return.
            for row in out.iter_mut() {
                *row = [0.0; NUM_CLASSES];
            }
            let mut acc = [#rt::Acc::ONE; NUM_DECOMPOSITIONS];
            #values
            let (l, w) = finish(&acc, #rt::log_scale(e, &ALL_UNKNOWN))?;
            #scatter
            Ok(l)
        }

        #checked
    }
}

/// `mpe`: the max-product value pass, then backtracking in the best decomposition's
/// components.
fn mpe(tpls: &[Tpl], cx: &Context, table: Table) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let table = bind_table(table, quote!(None));
    let checked = checked(
        &cx.l,
        &[
            " Writes the max-product (MPE) labelling into `labels` and returns its natural-log",
            " max-product value `max_d ln((1/D) Π_k maxprod T_k)`, ties broken towards the lowest",
            " decomposition.",
        ],
        "mpe",
        quote!(e: &Evidence, labels: &mut Labels),
        quote!(e, labels),
        TokenStream::new(),
    );
    let calls = per_template(tpls, |tp| {
        let stat = &tp.stat;
        quote!(#rt::mpe_labels(&#stat, e, table, d, labels);)
    });
    quote! {
        /// Like [`mpe`], without validating the evidence.
        pub fn mpe_unchecked(e: &Evidence, labels: &mut Labels) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            #table
            let acc = values(e, &ALL_UNKNOWN, table, true);
            let (Some(d), scale) = (#rt::best(&acc), #rt::log_scale(e, &ALL_UNKNOWN)) else {
                return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
            };
            let v = match acc.get(d) {
                Some(a) => scale + a.ln() - #rt::Real::ln(NUM_DECOMPOSITIONS as #t),
                None => #t::NEG_INFINITY,
            };
            if !(v > #t::NEG_INFINITY) {
                return Err(::graphspn_runtime::EvidenceError::ZeroLikelihood);
            }
            #calls
            Ok(v)
        }

        #checked
    }
}
