//! Shared template functions: one forward, one forward+backward (local posteriors) and
//! one max-product function per template SPN, emitted as straight-line Rust text.
//!
//! Every reachable SPN node becomes one `let` statement (products of leaf values,
//! weighted sums); sums with more than [`DENSE_MIN`] children read their weights from a
//! `static` array and call a vectorisable dot product. Zero-weight edges are dropped.
//! The backward sweep is straight-line too: in linear space it propagates adjoints
//! `∂T/∂v`, in log space it propagates flows `v·∂T/∂v / T ∈ [0, 1]`.

use std::collections::BTreeMap;

use proc_macro2::{Ident, TokenStream};
use quote::{ToTokens, format_ident, quote};

use crate::spn::{Node, Spn};

use super::analysis::Numerics;
use super::emit::{Lit, array, int, join};

/// Sums with more children than this use a `static` weight array and `dot_*`.
pub const DENSE_MIN: usize = 4;
/// Term lists longer than this are summed with `sum_*([..])` (flat array, no deep trees).
const FLAT_MIN: usize = 8;

/// What the emitter needs to know about one template.
pub struct TemplateCode<'a> {
    /// Function name prefix, e.g. `t0_star`.
    pub prefix: String,
    /// The template SPN.
    pub spn: &'a Spn,
    /// Linear or log space.
    pub numerics: Numerics,
    /// Number of classes.
    pub classes: usize,
}

/// A reachable non-leaf node with its zero-weight edges removed.
enum Op {
    Leaf(usize, usize),
    Sum(Vec<(usize, f64)>),
    Product(Vec<usize>),
}

fn ops(spn: &Spn) -> BTreeMap<usize, Op> {
    let mut reach = vec![false; spn.nodes.len()];
    reach[spn.root as usize] = true;
    let mut out = BTreeMap::new();
    for i in (0..spn.nodes.len()).rev() {
        if !reach[i] {
            continue;
        }
        let op = match &spn.nodes[i] {
            Node::Leaf { var, class } => Op::Leaf(*var as usize, *class as usize),
            Node::Sum { children, weights } => Op::Sum(
                children
                    .iter()
                    .zip(weights)
                    .filter(|(_, w)| **w > 0.0)
                    .map(|(&c, &w)| (c as usize, w))
                    .collect(),
            ),
            Node::Product { children } => {
                Op::Product(children.iter().map(|&c| c as usize).collect())
            }
        };
        match &op {
            Op::Leaf(..) => {}
            Op::Sum(ch) => ch.iter().for_each(|&(c, _)| reach[c] = true),
            Op::Product(ch) => ch.iter().for_each(|&c| reach[c] = true),
        }
        out.insert(i, op);
    }
    out
}

/// `terms` joined by `op`, as a flat `flat([..])` call when there are more than
/// [`FLAT_MIN`], or `empty` when there are none; and whether the result is an
/// operator chain of several terms (which needs brackets inside a product).
fn join_terms(
    terms: Vec<TokenStream>,
    op: TokenStream,
    flat: TokenStream,
    empty: TokenStream,
) -> (TokenStream, bool) {
    match terms.len() {
        0 => (empty, false),
        n if n > FLAT_MIN => {
            let terms = array(terms);
            (quote!(#flat(#terms)), false)
        }
        n => (join(terms, &op), n > 1),
    }
}

impl TemplateCode<'_> {
    fn n(&self) -> usize {
        self.spn.num_vars()
    }

    fn ident(&self, suffix: &str) -> Ident {
        format_ident!("{}_{}", self.prefix, suffix)
    }

    /// `x: &[[T; C]; N]`.
    fn arg_x(&self, l: &Lit) -> TokenStream {
        let (t, c, n) = (l.ty(), int(self.classes), int(self.n()));
        quote!(x: &[[#t; #c]; #n])
    }

    fn linear(&self) -> bool {
        matches!(self.numerics, Numerics::Linear { .. })
    }

    /// The `static` weight array of dense sum `i`.
    fn weights(&self, i: usize) -> Ident {
        format_ident!("W_{}_{}", self.prefix.to_uppercase(), i)
    }

    /// `terms` summed (`a + b`, or `sum_f32([..])` when long; `0.0` when empty).
    fn sum_of(&self, l: &Lit, terms: Vec<TokenStream>) -> (TokenStream, bool) {
        join_terms(terms, quote!(+), l.helper("sum"), quote!(0.0))
    }

    /// Statics (weight arrays) shared by this template's functions.
    pub fn statics(&self, l: &Lit) -> TokenStream {
        let mut out = TokenStream::new();
        if !self.linear() {
            return out;
        }
        let t = l.ty();
        for (i, op) in ops(self.spn) {
            if let Op::Sum(ch) = op
                && ch.len() > DENSE_MIN
            {
                let name = self.weights(i);
                let len = int(ch.len());
                let ws = array(ch.iter().map(|&(_, w)| l.num(w)));
                out.extend(quote!(static #name: [#t; #len] = #ws;));
            }
        }
        out
    }

    /// Forward statements; `max` selects max-product (sums become `argmax`).
    fn forward(&self, l: &Lit, max: bool, body: &mut TokenStream) {
        let t = l.ty();
        let ops = ops(self.spn);
        let node = |c: usize| format_ident!("n{c}");
        if !self.linear() {
            let ln_rows = l.helper("ln_rows");
            body.extend(quote!(let lx = #ln_rows(x);));
        }
        for (&i, op) in ops.iter() {
            let ni = node(i);
            let stmt = match op {
                Op::Leaf(v, c) => {
                    let (v, c) = (int(*v), int(*c));
                    if self.linear() {
                        quote!(let #ni = x[#v][#c];)
                    } else {
                        quote!(let #ni = lx[#v][#c];)
                    }
                }
                Op::Product(ch) => {
                    let terms = ch.iter().map(|&c| node(c).into_token_stream()).collect();
                    let (e, _) = if self.linear() {
                        join_terms(terms, quote!(*), l.helper("prod"), quote!(1.0))
                    } else {
                        self.sum_of(l, terms)
                    };
                    quote!(let #ni = #e;)
                }
                Op::Sum(ch) => {
                    let terms: Vec<TokenStream> = ch
                        .iter()
                        .map(|&(c, w)| {
                            let c = node(c);
                            if self.linear() {
                                let w = l.num(w);
                                quote!(#w * #c)
                            } else {
                                let w = l.num(w.ln());
                                quote!(#w + #c)
                            }
                        })
                        .collect();
                    if ch.is_empty() {
                        let z = if self.linear() {
                            quote!(0.0)
                        } else {
                            quote!(#t::NEG_INFINITY)
                        };
                        let ai = format_ident!("a{i}");
                        if max {
                            quote!(let (#ni, #ai) = (#z, 0u16);)
                        } else {
                            quote!(let #ni: #t = #z;)
                        }
                    } else if max {
                        let (f, ai, terms) =
                            (l.helper("argmax"), format_ident!("a{i}"), array(terms));
                        quote!(let (#ni, #ai) = #f(#terms);)
                    } else if !self.linear() {
                        let (f, terms) = (l.helper("lse"), array(terms));
                        quote!(let #ni = #f(#terms);)
                    } else if ch.len() > DENSE_MIN {
                        let (f, w) = (l.helper("dot"), self.weights(i));
                        let vs = array(ch.iter().map(|&(c, _)| node(c)));
                        quote!(let #ni = #f(&#w, &#vs);)
                    } else {
                        let e = join(terms, &quote!(+));
                        quote!(let #ni = #e;)
                    }
                }
            };
            body.extend(stmt);
        }
    }

    /// `fn <prefix>_fwd(x) -> value` (linear value, or log value in log space).
    pub fn fwd(&self, l: &Lit) -> TokenStream {
        let mut body = TokenStream::new();
        self.forward(l, false, &mut body);
        let (name, x, t, root) = (
            self.ident("fwd"),
            self.arg_x(l),
            l.ty(),
            format_ident!("n{}", self.spn.root),
        );
        quote!(#[inline(never)] fn #name(#x) -> #t { #body #root })
    }

    /// `fn <prefix>_max(x) -> value`: the max-product value (through `_mpe`, its
    /// labelling discarded).
    pub fn max(&self, l: &Lit) -> TokenStream {
        let (name, mpe, x, t, n) = (
            self.ident("max"),
            self.ident("mpe"),
            self.arg_x(l),
            l.ty(),
            int(self.n()),
        );
        quote!(#[inline(never)] fn #name(#x) -> #t { let mut lab = [[0u16; #n]; 1]; #mpe(x, &mut lab) })
    }

    /// `fn <prefix>_post(x, post) -> value`: also writes the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T`.
    pub fn post(&self, l: &Lit) -> TokenStream {
        let t = l.ty();
        let ops = ops(self.spn);
        let mut body = TokenStream::new();
        self.forward(l, false, &mut body);
        let root = self.spn.root as usize;
        let node = |c: usize| format_ident!("n{c}");
        let adjoint = |c: usize| format_ident!("g{c}");
        // Terms flowing into each node, filled top-down.
        let mut terms: BTreeMap<usize, Vec<TokenStream>> = BTreeMap::new();
        // Per leaf (variable, class): the adjoint of each leaf node, and whether it is
        // a `+` chain.
        let mut leaf_terms: BTreeMap<(usize, usize), Vec<(TokenStream, bool)>> = BTreeMap::new();
        for (&i, op) in ops.iter().rev() {
            let (g, chain) = if i == root {
                (quote!(1.0), false)
            } else {
                self.sum_of(l, terms.remove(&i).unwrap_or_default())
            };
            if let Op::Leaf(v, c) = op {
                leaf_terms.entry((*v, *c)).or_default().push((g, chain));
                continue;
            }
            let gi = adjoint(i);
            body.extend(quote!(let #gi: #t = #g;));
            match op {
                Op::Leaf(..) => {}
                Op::Sum(ch) => {
                    for (j, &(c, w)) in ch.iter().enumerate() {
                        let term = if !self.linear() {
                            let (flow, w, nc, ni) =
                                (l.helper("flow"), l.num(w.ln()), node(c), node(i));
                            quote!(#flow(#gi, #w + #nc, #ni))
                        } else if ch.len() > DENSE_MIN {
                            let (ws, j) = (self.weights(i), int(j));
                            quote!(#ws[#j] * #gi)
                        } else {
                            let w = l.num(w);
                            quote!(#w * #gi)
                        };
                        terms.entry(c).or_default().push(term);
                    }
                }
                Op::Product(ch) => {
                    for (j, &c) in ch.iter().enumerate() {
                        let term = if self.linear() {
                            let others = ch
                                .iter()
                                .enumerate()
                                .filter(|&(k, _)| k != j)
                                .map(|(_, &o)| node(o));
                            join(std::iter::once(gi.clone()).chain(others), &quote!(*))
                        } else {
                            quote!(#gi)
                        };
                        terms.entry(c).or_default().push(term);
                    }
                }
            }
        }
        let n_root = node(root);
        if self.linear() {
            body.extend(quote!(let inv = 1.0 / #n_root;));
        }
        for ((v, c), mut ts) in leaf_terms {
            // A `+` chain is bracketed inside the product below.
            let (g, chain) = if ts.len() == 1 {
                ts.remove(0)
            } else {
                self.sum_of(l, ts.into_iter().map(|(g, _)| g).collect())
            };
            let (v, c) = (int(v), int(c));
            body.extend(if !self.linear() {
                quote!(post[#v][#c] = #g;)
            } else if chain {
                quote!(post[#v][#c] = x[#v][#c] * (#g) * inv;)
            } else {
                quote!(post[#v][#c] = x[#v][#c] * #g * inv;)
            });
        }
        let (name, x, cl, n) = (
            self.ident("post"),
            self.arg_x(l),
            int(self.classes),
            int(self.n()),
        );
        quote!(#[inline(never)] fn #name(#x, post: &mut [[#t; #cl]; #n]) -> #t { #body #n_root })
    }

    /// `fn <prefix>_mpe(x, lab) -> value`: max-product value (linear or log) and the
    /// argmax labelling by backtracking (ties → lowest child index) into `lab[0]` (a
    /// per-node template's group has one lane).
    pub fn mpe(&self, l: &Lit) -> TokenStream {
        let ops = ops(self.spn);
        let mut body = TokenStream::new();
        self.forward(l, true, &mut body);
        let root = self.spn.root as usize;
        let mut terms: BTreeMap<usize, Vec<TokenStream>> = BTreeMap::new();
        for (&i, op) in ops.iter().rev() {
            let b = if i == root {
                quote!(true)
            } else {
                match terms.remove(&i) {
                    Some(ts) if !ts.is_empty() => join(ts, &quote!(|)),
                    _ => quote!(false),
                }
            };
            let bi = format_ident!("b{i}");
            body.extend(quote!(let #bi: bool = #b;));
            match op {
                Op::Leaf(v, c) => {
                    let (v, c) = (int(*v), int(*c));
                    body.extend(quote!(if #bi { lab[#v] = #c; }));
                }
                Op::Sum(ch) => {
                    let ai = format_ident!("a{i}");
                    for (j, &(c, _)) in ch.iter().enumerate() {
                        let j = int(j);
                        terms.entry(c).or_default().push(quote!(#bi & (#ai == #j)));
                    }
                }
                Op::Product(ch) => {
                    for &c in ch {
                        terms.entry(c).or_default().push(quote!(#bi));
                    }
                }
            }
        }
        let (name, x, n, t, n_root) = (
            self.ident("mpe"),
            self.arg_x(l),
            int(self.n()),
            l.ty(),
            format_ident!("n{root}"),
        );
        quote!(#[inline(never)] fn #name(#x, lab: &mut [[u16; #n]; 1]) -> #t { let lab = &mut lab[0]; #body #n_root })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codegen::Precision;

    /// `0.5·x0[0]·x1[0] + 0.5·x0[1]·x1[1] + 0·x0[0]·x1[1]`: leaves 0–3, products 4–6
    /// (6 reached only through the zero weight), root sum 7.
    fn with_zero_edge() -> Spn {
        let mut nodes: Vec<Node> = (0..2)
            .flat_map(|var| (0..2).map(move |class| Node::Leaf { var, class }))
            .collect();
        for children in [vec![0, 2], vec![1, 3], vec![0, 3]] {
            nodes.push(Node::Product { children });
        }
        nodes.push(Node::Sum {
            children: vec![4, 5, 6],
            weights: vec![0.5, 0.5, 0.0],
        });
        Spn {
            classes: vec![2, 2],
            root: 7,
            nodes,
        }
    }

    /// A zero-weight edge is dropped, and with it every node only that edge reaches:
    /// no statement computes it, in linear or log space (where its weight would be
    /// `ln 0 = -∞`).
    #[test]
    fn zero_weight_edges_and_what_only_they_reach_emit_no_code() {
        let spn = with_zero_edge();
        spn.validate().unwrap();
        let ops = ops(&spn);
        assert_eq!(
            ops.keys().copied().collect::<Vec<_>>(),
            [0, 1, 2, 3, 4, 5, 7]
        );
        assert!(matches!(&ops[&7], Op::Sum(terms) if terms == &[(4, 0.5), (5, 0.5)]));
        let l = Lit::new(Precision::F32);
        for numerics in [
            Numerics::Linear {
                min_value: 0.0,
                min_max: 0.0,
            },
            Numerics::Log,
        ] {
            let code = TemplateCode {
                prefix: "t0_pair".into(),
                spn: &spn,
                numerics,
                classes: 2,
            };
            let src = code.fwd(&l).to_string();
            assert!(src.contains("n5") && !src.contains("n6"), "{src}");
            assert!(!src.contains("INFINITY"), "{src}");
        }
    }
}
