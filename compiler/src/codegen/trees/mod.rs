//! Code generation for tree mixtures ([`crate::treemix`]): the module of one map with
//! the same public API as a GraphSPN module.
//!
//! # Shape
//!
//! The model's potentials become `static` arrays (`ψ` by columns and `u`, scaled to a
//! largest entry of 1, classes in lanes: one `f32` per class on microcontrollers, rows
//! of `f32x8` / `f64x4` vectors padded with zeros on SIMD hosts) and every spanning
//! forest a set of `static` tables ([`plan::ForestPlan`]: depth-first post-order with
//! depths, parents, children, roots, `ln Z_t`). One generic driver in
//! `graphspn_runtime::__private::tree` runs over them, so the machine code is the same
//! for every map of a model's class count; only the tables grow with the map.
//!
//! # Entry points
//!
//! `log_likelihood` / `labelled_log_likelihood` (one post-order sweep per forest with a
//! stack of one row per depth), `marginals` (per forest a stored upward pass and a
//! downward pass: `O(places · C)` scratch), `mpe` (max-product sweeps, then one sweep of
//! the best forest with an arg-max byte per place and class), each with its
//! `_unchecked` twin, the streaming `State` (every forest's upward messages cached; an
//! update recomputes the place's paths to the roots) and the `CompiledMap` impl —
//! wrappers, constants and the impl shared with the GraphSPN emitter
//! ([`super::surface`]).

mod api;
mod plan;

use proc_macro2::TokenStream;
use quote::{ToTokens, quote};

use crate::map::TopoMap;
use crate::treemix::{SpanningTrees, TreeMixture};

use super::emit::{array, int, int_array, rt};
use super::surface::{CodeReport, Surface, compiled_map_impl, constants_and_types};
use super::{CodegenError, CodegenOptions};
use graphspn_runtime::__private::FactorCache;
use plan::{Context, ForestPlan, Potentials};

/// The whole module as tokens, and its report.
pub fn module(
    model: &TreeMixture,
    map: &TopoMap,
    trees: &SpanningTrees,
    options: &CodegenOptions,
) -> Result<(TokenStream, CodeReport), CodegenError> {
    crate::treemix::check_inputs(model, map, trees)?;
    let cx = Context::new(model, trees, options)?;
    let pot = Potentials::new(model, &cx);
    let plans: Vec<ForestPlan> = trees
        .forests
        .iter()
        .map(|f| ForestPlan::new(f, &pot, cx.c))
        .collect();
    let (mut report, cache) = plan::report(&plans, &cx, options.stack_budget());
    report.message_error = pot.fixed.as_ref().map(|f| f.error);
    report.check_budget(options)?;
    let constants = constants_and_types(&Surface {
        l: &cx.l,
        family: "tree_mixture",
        n: cx.n,
        c: cx.c,
        mixture: cx.t,
        mixture_doc: " Number of spanning trees mixed (with uniform weights) at the root.",
        lanes: cx.width,
        components: cx.t * cx.n,
        report: &report,
        place_ids: map.places().map(|p| p.id).collect(),
        class_names: model.classes.names(),
        evidence_exponent: model.evidence_exponent,
    });
    let items = items(model, &cx);
    let tables = forest_tables(&plans, &cx);
    let statics = model_static(&pot, cache, &cx);
    let stateless = api::stateless_api(&cx, report.message_error);
    let state = api::state_api(&cx);
    let compiled_map = compiled_map_impl(&cx.l);
    let tokens = quote! {
        #constants
        #items
        #tables
        #statics
        #stateless
        #state
        #compiled_map
    };
    Ok((tokens, report))
}

/// The lane vector `V`, the row and stack sizes and the model's public numbers.
fn items(model: &TreeMixture, cx: &Context) -> TokenStream {
    let rt = rt();
    let t = cx.l.ty();
    let v_type = match (cx.width, cx.l.is_f32()) {
        (1, _) if cx.soft => quote!(#rt::SoftF32),
        (1, _) => quote!(#t),
        (_, true) => quote!(#rt::Lanes32),
        (_, false) => quote!(#rt::Lanes64),
    };
    let (k, h, trees) = (int(cx.k), int(cx.h), int(cx.t));
    let average = matches!(model.mixing, crate::spn::Mixing::Average);
    quote! {
        /// The lane vector of a row of classes.
        type V = #v_type;
        /// Lane vectors per row of classes.
        const K: usize = #k;
        /// Rows of the per-depth stacks of the passes (the forests' largest height + 2).
        const H: usize = #h;
        /// Number of spanning trees mixed at the root (`NUM_DECOMPOSITIONS`).
        pub const NUM_TREES: usize = #trees;
        /// Whether `marginals` are the mean of the trees' exact marginals (`true`) or the
        /// exact marginals of the mixture (`false`).
        pub const AVERAGE_MIXING: bool = #average;
        static ALL_UNKNOWN: Labels = [UNKNOWN; NUM_PLACES];
    }
}

/// `u16` literals of `items` as an array expression.
fn u16s(items: impl IntoIterator<Item = usize>) -> TokenStream {
    int_array(items)
}

/// The `static` tables of every forest and the `FORESTS` array.
fn forest_tables(plans: &[ForestPlan], cx: &Context) -> TokenStream {
    let rt = rt();
    let t = cx.l.ty();
    let none = usize::from(u16::MAX);
    let mut out = TokenStream::new();
    let mut forests = Vec::new();
    for (i, p) in plans.iter().enumerate() {
        let [post, parent, start, kids, roots] = ["POST", "PARENT", "KID_START", "KIDS", "ROOTS"]
            .map(|s| quote::format_ident!("F{i}_{s}"));
        let post_rows = array(p.post.iter().map(|&[v, d]| int_array([v, d])));
        let parents = u16s(p.parent.iter().map(|q| q.unwrap_or(none)));
        let (nk, nr, ns) = (
            int(p.kids.len()),
            int(p.roots.len()),
            int(p.kid_start.len()),
        );
        let (starts, kid_list, root_list) = (
            u16s(p.kid_start.iter().copied()),
            u16s(p.kids.iter().copied()),
            u16s(p.roots.iter().copied()),
        );
        out.extend(quote! {
            static #post: [[u16; 2]; NUM_PLACES] = #post_rows;
            static #parent: [u16; NUM_PLACES] = #parents;
            static #start: [u16; #ns] = #starts;
            static #kids: [u16; #nk] = #kid_list;
            static #roots: [u16; #nr] = #root_list;
        });
        let (z_exp, z_rem) = (
            proc_macro2::Literal::i32_unsuffixed(p.z_exp),
            cx.l.num(p.z_rem),
        );
        forests.push(quote! {
            #rt::Forest { post: &#post, parent: &#parent, kid_start: &#start, kids: &#kids, roots: &#roots, z_exp: #z_exp, z_rem: #z_rem }
        });
    }
    let forests = array(forests);
    out.extend(quote! {
        /// The spanning forests, in mixture order.
        static FORESTS: [#rt::Forest<#t>; NUM_TREES] = #forests;
    });
    out
}

/// One row of lane vectors holding `values` (one per class; padding lanes `pad`).
fn row(values: &[f64], pad: f64, cx: &Context) -> TokenStream {
    let rt = rt();
    let lanes = cx.k * cx.width;
    let scalars: Vec<TokenStream> = (0..lanes)
        .map(|i| cx.l.num(values.get(i).copied().unwrap_or(pad)))
        .collect();
    if cx.soft {
        return array(scalars.iter().map(|x| quote!(#rt::SoftF32(#x))));
    }
    if cx.width == 1 {
        return array(scalars);
    }
    let ctor = if cx.l.is_f32() {
        quote!(#rt::Lanes32::new)
    } else {
        quote!(#rt::Lanes64::new)
    };
    array(scalars.chunks(cx.width).map(|ch| quote!(#ctor([#(#ch),*]))))
}

/// `MODEL`: the potentials (ψ by columns), `γ`, the mixing and the forests.
fn model_static(pot: &Potentials, cache: FactorCache, cx: &Context) -> TokenStream {
    let rt = rt();
    let c = cx.c;
    let columns = |m: &[f64]| {
        array((0..c).map(|j| {
            let col: Vec<f64> = (0..c).map(|a| m[a * c + j]).collect();
            row(&col, 0.0, cx)
        }))
    };
    let (up, down, folded) = (columns(&pot.up), columns(&pot.down), pot.folded);
    let unary = row(&pot.unary, 0.0, cx);
    let pad = row(&vec![0.0; c], 1.0, cx);
    let fixed = match &pot.fixed {
        Some(f) => {
            let rows = |m: &[u32]| {
                array(
                    m.chunks(c)
                        .map(|r| array(r.iter().map(|&x| int(x as usize)))),
                )
            };
            let (fu, fd) = (rows(&f.up), rows(&f.down));
            quote!(Some(#rt::FixedMatrices { up: #fu, down: #fd }))
        }
        None => quote!(None),
    };
    let v = quote!(V).into_token_stream();
    let FactorCache {
        values,
        marginals,
        state,
    } = cache;
    quote! {
        /// The compiled model: the message matrices by columns and `u` (largest entry 1),
        /// where `u` enters, `γ`, the mixing, the forests, which entry points keep a
        /// table of every place's `φ`, and the Q0.32 message matrices by rows where
        /// messages are computed in fixed point.
        static MODEL: #rt::TreeModel<#v, NUM_CLASSES, K> = #rt::TreeModel {
            psi_up: #up,
            psi_down: #down,
            unary: #unary,
            folded: #folded,
            pad: #pad,
            gamma: EVIDENCE_EXPONENT,
            average: AVERAGE_MIXING,
            forests: &FORESTS,
            cache: #rt::FactorCache { values: #values, marginals: #marginals, state: #state },
            fixed: #fixed,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::super::emit::Lit;
    use super::*;

    #[test]
    fn rows_pad_to_whole_vectors() {
        let cx_of = |width: usize| Context {
            l: Lit::new(super::super::Precision::F32),
            n: 1,
            c: 3,
            t: 1,
            width,
            k: 3usize.div_ceil(width),
            h: 2,
            scalar: 4,
            soft: false,
        };
        let s = row(&[0.5, 0.25, 1.0], 0.0, &cx_of(1)).to_string();
        assert_eq!(s, "[0.5f32 , 0.25f32 , 1.0f32]");
        let v = row(&[0.5, 0.25, 1.0], 1.0, &cx_of(8)).to_string();
        assert!(
            v.contains("Lanes32 :: new ([0.5f32 , 0.25f32 , 1.0f32 , 1.0f32"),
            "{v}"
        );
    }
}
