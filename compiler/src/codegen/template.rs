//! Shared template functions: one forward, one forward+backward (local posteriors) and
//! one max-product function per template SPN, emitted as straight-line Rust text.
//!
//! Every reachable SPN node becomes one `let` statement (products of leaf values,
//! weighted sums); sums with more than [`DENSE_MIN`] children read their weights from a
//! `static` array and call a vectorisable dot product. Zero-weight edges are dropped.
//! The backward sweep is straight-line too: in linear space it propagates adjoints
//! `∂T/∂v`, in log space it propagates flows `v·∂T/∂v / T ∈ [0, 1]`.

use std::collections::BTreeMap;
use std::fmt::Write;

use crate::spn::{Node, Spn};

use super::analysis::Numerics;
use super::emit::{Lit, P};

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

fn join(terms: &[String], op: &str, flat: &str, empty: &str) -> String {
    match terms.len() {
        0 => empty.to_string(),
        n if n > FLAT_MIN => format!("{flat}([{}])", terms.join(", ")),
        _ => terms.join(op),
    }
}

impl TemplateCode<'_> {
    fn n(&self) -> usize {
        self.spn.num_vars()
    }

    fn sig_x(&self, l: &Lit) -> String {
        format!("x: &[[{}; {}]; {}]", l.t, self.classes, self.n())
    }

    fn linear(&self) -> bool {
        matches!(self.numerics, Numerics::Linear { .. })
    }

    /// Statics (weight arrays) shared by this template's functions.
    pub fn statics(&self, l: &Lit, out: &mut String) {
        if !self.linear() {
            return;
        }
        for (i, op) in ops(self.spn) {
            if let Op::Sum(ch) = op
                && ch.len() > DENSE_MIN
            {
                let ws: Vec<String> = ch.iter().map(|&(_, w)| l.num(w)).collect();
                let _ = writeln!(
                    out,
                    "static W_{}_{i}: [{}; {}] = [{}];",
                    self.prefix.to_uppercase(),
                    l.t,
                    ch.len(),
                    ws.join(", ")
                );
            }
        }
    }

    /// Forward statements; `max` selects max-product (sums become `argmax`).
    fn forward(&self, l: &Lit, max: bool, body: &mut String) {
        let t = l.t;
        let ops = ops(self.spn);
        if !self.linear() {
            let _ = writeln!(body, "let lx = {P}ln_rows_{t}(x);");
        }
        for (&i, op) in ops.iter() {
            let stmt = match op {
                Op::Leaf(v, c) if self.linear() => format!("let n{i} = x[{v}][{c}];"),
                Op::Leaf(v, c) => format!("let n{i} = lx[{v}][{c}];"),
                Op::Product(ch) => {
                    let terms: Vec<String> = ch.iter().map(|c| format!("n{c}")).collect();
                    if self.linear() {
                        format!(
                            "let n{i} = {};",
                            join(&terms, " * ", &format!("{P}prod_{t}"), "1.0")
                        )
                    } else {
                        format!(
                            "let n{i} = {};",
                            join(&terms, " + ", &format!("{P}sum_{t}"), "0.0")
                        )
                    }
                }
                Op::Sum(ch) => {
                    let terms: Vec<String> = if self.linear() {
                        ch.iter()
                            .map(|&(c, w)| format!("{} * n{c}", l.num(w)))
                            .collect()
                    } else {
                        ch.iter()
                            .map(|&(c, w)| format!("{} + n{c}", l.num(w.ln())))
                            .collect()
                    };
                    if ch.is_empty() {
                        let z = if self.linear() {
                            "0.0".to_string()
                        } else {
                            format!("{t}::NEG_INFINITY")
                        };
                        if max {
                            format!("let (n{i}, a{i}) = ({z}, 0u16);")
                        } else {
                            format!("let n{i}: {t} = {z};")
                        }
                    } else if max {
                        format!("let (n{i}, a{i}) = {P}argmax_{t}([{}]);", terms.join(", "))
                    } else if !self.linear() {
                        format!("let n{i} = {P}lse_{t}([{}]);", terms.join(", "))
                    } else if ch.len() > DENSE_MIN {
                        let vs: Vec<String> = ch.iter().map(|&(c, _)| format!("n{c}")).collect();
                        format!(
                            "let n{i} = {P}dot_{t}(&W_{}_{i}, &[{}]);",
                            self.prefix.to_uppercase(),
                            vs.join(", ")
                        )
                    } else {
                        format!("let n{i} = {};", terms.join(" + "))
                    }
                }
            };
            body.push_str(&stmt);
            body.push('\n');
        }
    }

    /// `fn <prefix>_fwd(x) -> value` (linear value, or log value in log space).
    pub fn fwd(&self, l: &Lit, out: &mut String) {
        let mut body = String::new();
        self.forward(l, false, &mut body);
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_fwd({}) -> {} {{ {body} n{} }}",
            self.prefix,
            self.sig_x(l),
            l.t,
            self.spn.root
        );
    }

    /// `fn <prefix>_post(x, post) -> value`: also writes the local posteriors
    /// `post[i][c] = x_i[c]·∂T/∂x_i[c] / T`.
    pub fn post(&self, l: &Lit, out: &mut String) {
        let t = l.t;
        let ops = ops(self.spn);
        let mut body = String::new();
        self.forward(l, false, &mut body);
        let root = self.spn.root as usize;
        // Terms flowing into each node, filled top-down.
        let mut terms: BTreeMap<usize, Vec<String>> = BTreeMap::new();
        let mut leaf_terms: BTreeMap<(usize, usize), Vec<String>> = BTreeMap::new();
        for (&i, op) in ops.iter().rev() {
            let g = if i == root {
                "1.0".to_string()
            } else {
                join(
                    terms.get(&i).map_or(&[][..], |v| v),
                    " + ",
                    &format!("{P}sum_{t}"),
                    "0.0",
                )
            };
            match op {
                Op::Leaf(v, c) => {
                    leaf_terms.entry((*v, *c)).or_default().push(g);
                    continue;
                }
                _ => {
                    let _ = writeln!(body, "let g{i}: {t} = {g};");
                }
            }
            match op {
                Op::Leaf(..) => {}
                Op::Sum(ch) => {
                    for (j, &(c, w)) in ch.iter().enumerate() {
                        let term = if self.linear() {
                            if ch.len() > DENSE_MIN {
                                format!("W_{}_{i}[{j}] * g{i}", self.prefix.to_uppercase())
                            } else {
                                format!("{} * g{i}", l.num(w))
                            }
                        } else {
                            format!("{P}flow_{t}(g{i}, {} + n{c}, n{i})", l.num(w.ln()))
                        };
                        terms.entry(c).or_default().push(term);
                    }
                }
                Op::Product(ch) => {
                    for (j, &c) in ch.iter().enumerate() {
                        let term = if self.linear() {
                            let mut f = vec![format!("g{i}")];
                            f.extend(
                                ch.iter()
                                    .enumerate()
                                    .filter(|&(k, _)| k != j)
                                    .map(|(_, o)| format!("n{o}")),
                            );
                            f.join(" * ")
                        } else {
                            format!("g{i}")
                        };
                        terms.entry(c).or_default().push(term);
                    }
                }
            }
        }
        if self.linear() {
            let _ = writeln!(body, "let inv = 1.0 / n{root};");
        }
        for ((v, c), ts) in &leaf_terms {
            let g = join(ts, " + ", &format!("{P}sum_{t}"), "0.0");
            if self.linear() {
                let g = if g.contains(" + ") && !g.starts_with(P) {
                    format!("({g})")
                } else {
                    g
                };
                let _ = writeln!(body, "post[{v}][{c}] = x[{v}][{c}] * {g} * inv;");
            } else {
                let _ = writeln!(body, "post[{v}][{c}] = {g};");
            }
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_post({}, post: &mut [[{t}; {}]; {}]) -> {t} {{ {body} n{root} }}",
            self.prefix,
            self.sig_x(l),
            self.classes,
            self.n()
        );
    }

    /// `fn <prefix>_mpe(x, lab) -> value`: max-product value (linear or log) and the
    /// argmax labelling by backtracking (ties → lowest child index).
    pub fn mpe(&self, l: &Lit, out: &mut String) {
        let ops = ops(self.spn);
        let mut body = String::new();
        self.forward(l, true, &mut body);
        let root = self.spn.root as usize;
        let mut terms: BTreeMap<usize, Vec<String>> = BTreeMap::new();
        for (&i, op) in ops.iter().rev() {
            let b = if i == root {
                "true".to_string()
            } else {
                let ts = terms.get(&i).map_or(&[][..], |v| v);
                if ts.is_empty() {
                    "false".to_string()
                } else {
                    ts.join(" | ")
                }
            };
            let _ = writeln!(body, "let b{i}: bool = {b};");
            match op {
                Op::Leaf(v, c) => {
                    let _ = writeln!(body, "if b{i} {{ lab[{v}] = {c}; }}");
                }
                Op::Sum(ch) => {
                    for (j, &(c, _)) in ch.iter().enumerate() {
                        terms
                            .entry(c)
                            .or_default()
                            .push(format!("b{i} & (a{i} == {j})"));
                    }
                }
                Op::Product(ch) => {
                    for &c in ch {
                        terms.entry(c).or_default().push(format!("b{i}"));
                    }
                }
            }
        }
        let _ = writeln!(
            out,
            "#[inline(never)] fn {}_mpe({}, lab: &mut [u16; {}]) -> {} {{ {body} n{root} }}",
            self.prefix,
            self.sig_x(l),
            self.n(),
            l.t
        );
    }
}
