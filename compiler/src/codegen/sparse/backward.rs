//! The backward sweep of the floor + sparse posterior function: each row's adjoint
//! carried through its floor term and its groups of above-floor terms to the
//! adjoints of the segment's inputs (in fixed-point code at each vector's scale, see
//! `scaling.rs`).

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::{Groups, Row, SparseCode, group_terms, other_inputs};
use crate::codegen::emit::{Lit, int, join, rt};
use crate::codegen::kernels::Segment;

impl SparseCode<'_> {
    /// Backward sweep of [`Self::grouped_sum`]: adds row `m`'s adjoint `g_m`, through
    /// its above-floor terms, to the adjoints of the segment's inputs. A group of one
    /// term adds `g_m·d·(the other factors)` to each factor's adjoint; a larger group
    /// adds `g_m·q` to its shared factor `a[i]` and, with `h = g_m·a[i]`, `h·d·(the
    /// other factors)` to the rest of each tuple. Returns the multiply count.
    pub(super) fn grouped_adjoints(
        &self,
        l: &Lit,
        seg: &Segment,
        at: (usize, usize, usize),
        row: &Row,
        body: &mut TokenStream,
    ) -> usize {
        let mut ops = 0;
        let gm = {
            let (gb, mi) = (format_ident!("g{}", at.0), int(at.2));
            quote!(#gb[#mi])
        };
        // Fixed point: `g_m` is kept scaled by `2^sb`, each input's adjoints by theirs.
        let sb = self.adjoint_shift(self.plan.n + at.0);
        let scales: Vec<i32> = seg.inputs.iter().map(|&g| self.adjoint_shift(g)).collect();
        let mut spread = |t: usize, h: &Ident, sh: i32, skip: Option<usize>, body: &mut _| {
            ops += self.spread(seg, &scales, (t, h, sh), skip, body);
        };
        let Groups { pos, groups } = group_terms(seg, row);
        let h = format_ident!("h");
        let hd = format_ident!("hd");
        for (gi, (i, terms)) in groups.iter().enumerate() {
            if let [(t, d, _)] = terms[..] {
                // `h = g_m·d`, scaled by as much of the smallest target scale as the
                // constant allows.
                let up = self.fold(&[d], scales.iter().map(|&s| s - sb).min().unwrap_or(0));
                let w = self.weight(l, d * 2f64.powi(up));
                self.add_backward_units(2.0, sb + up);
                body.extend(quote!(let #h = #gm * V::splat(#w);));
                spread(t, &h, sb + up, None, body);
                continue;
            }
            let (q, a) = (Self::inner(&at, gi), self.elem(seg.inputs[pos], *i));
            let (target, ii) = (self.adjoint_name(seg.inputs[pos]), int(*i));
            // `g_m·q`: `q` is kept scaled by `2^s` (fixed point), so the product is
            // scaled by `2^(sb + s)`; shifted to the target's scale.
            let s = self.group_shift(seg, pos, terms) as i32;
            self.add_backward_units(1.0, sb + s);
            let up = scales[pos] - sb - s;
            body.extend(if up == 0 {
                quote!(#target[#ii] = Lanes::mul_add(#gm, #q, #target[#ii]);)
            } else {
                let v = self.rescale(quote!(#gm * #q), up, scales[pos]);
                quote!(#target[#ii] = #target[#ii] + #v;)
            });
            self.add_backward_units(1.0, sb);
            body.extend(quote!(let #h = #gm * #a;));
            for &(t, d, _) in terms {
                if let [_, _] = seg.inputs[..] {
                    // Two inputs: the other factor's adjoint gets `h·d` in one step.
                    let other = 1 - pos;
                    let up = self.fold(&[d], scales[other] - sb);
                    let w = self.weight(l, d * 2f64.powi(up));
                    self.add_backward_units(2.0, sb + up);
                    let (vector, j) = (
                        self.adjoint_name(seg.inputs[other]),
                        int(seg.tuple(t)[other]),
                    );
                    let rest = scales[other] - sb - up;
                    body.extend(if rest == 0 {
                        quote!(#vector[#j] = Lanes::mul_add(#h, V::splat(#w), #vector[#j]);)
                    } else {
                        let v = self.rescale(quote!(#h * V::splat(#w)), rest, scales[other]);
                        quote!(#vector[#j] = #vector[#j] + #v;)
                    });
                } else {
                    let lowest = (0..scales.len())
                        .filter(|&q| q != pos)
                        .map(|q| scales[q] - sb)
                        .min()
                        .unwrap_or(0);
                    let up = self.fold(&[d], lowest);
                    let w = self.weight(l, d * 2f64.powi(up));
                    self.add_backward_units(2.0, sb + up);
                    body.extend(quote!(let #hd = #h * V::splat(#w);));
                    spread(t, &hd, sb + up, Some(pos), body);
                }
            }
        }
        // Groups: one multiply-add for `a[i]`, one multiply for `h` and one per term
        // (`h·d`); a group of one term: `g_m·d`.
        ops + groups
            .iter()
            .map(|(_, t)| if t.len() > 1 { 2 + t.len() } else { 1 })
            .sum::<usize>()
    }

    /// `target += h·(the factors of tuple t but those at q and `skip`)`, for every
    /// position q but `skip`: `(t, h, sh)` with `h` scaled by `2^sh` (fixed point),
    /// each target's adjoints by theirs in `scales` (a larger scale is an exact left
    /// shift). Returns the multiply count.
    pub(super) fn spread(
        &self,
        seg: &Segment,
        scales: &[i32],
        (t, h, sh): (usize, &Ident, i32),
        skip: Option<usize>,
        body: &mut TokenStream,
    ) -> usize {
        let mut ops = 0;
        let idx = seg.tuple(t);
        for (q, &g) in seg.inputs.iter().enumerate() {
            if Some(q) == skip {
                continue;
            }
            let (vector, i) = (self.adjoint_name(g), int(idx[q]));
            let target = quote!(#vector[#i]);
            let left_out: Vec<usize> = [Some(q), skip].into_iter().flatten().collect();
            let up = scales[q] - sh;
            body.extend(match self.product(seg, t, &left_out) {
                (Some(o), n) => {
                    ops += n;
                    self.add_backward_units(n as f64, sh);
                    if up == 0 {
                        quote!(#target = Lanes::mul_add(#o, #h, #target);)
                    } else {
                        let v = self.rescale(quote!(#o * #h), up, scales[q]);
                        quote!(#target = #target + #v;)
                    }
                }
                (None, _) => {
                    let v = self.rescale(quote!(#h), up, scales[q]);
                    quote!(#target = #target + #v;)
                }
            });
        }
        ops
    }

    /// Backward sweep of a segment's floor terms (rows `floors`: `(row, floor)` of
    /// block `b`): `gf = Σ g_m·f_m`, and `gf` times the other inputs' sums added to
    /// every entry of each input's adjoints. Returns the multiply count.
    pub(super) fn floor_adjoints(
        &self,
        l: &Lit,
        b: usize,
        seg: &Segment,
        floors: &[(usize, f64)],
        body: &mut TokenStream,
    ) -> usize {
        if floors.is_empty() {
            return 0;
        }
        let (p, rt, gb) = (self.plan, rt(), format_ident!("g{b}"));
        let mut ops = 0;
        // Fixed point: `gf` is scaled by `2^sf`, as much of the inputs'
        // smallest adjoint scale as the floor constants allow.
        let sb = self.adjoint_shift(p.n + b);
        let scales: Vec<i32> = seg.inputs.iter().map(|&g| self.adjoint_shift(g)).collect();
        let lowest = scales.iter().map(|&s| s - sb).min().unwrap_or(0);
        let up = self.fold(&floors.iter().map(|f| f.1).collect::<Vec<_>>(), lowest);
        let sf = sb + up;
        let terms: Vec<TokenStream> = floors
            .iter()
            .map(|&(m, f)| {
                let (m, f) = (int(m), self.weight(l, f * 2f64.powi(up)));
                quote!(#gb[#m] * V::splat(#f))
            })
            .collect();
        ops += terms.len();
        self.add_backward_units(2.0 * terms.len() as f64, sf);
        let terms = join(terms, &quote!(+));
        body.extend(quote!(let gf = #terms;));
        for (q, &g) in seg.inputs.iter().enumerate() {
            let others: Vec<Ident> = other_inputs(seg, q)
                .map(|o| format_ident!("sv{o}"))
                .collect();
            let others_len = others.len();
            let v = if others.is_empty() {
                quote!(gf)
            } else {
                ops += others.len();
                let bits: u32 = other_inputs(seg, q).map(|o| self.sum_bits(o)).sum();
                let others = join(others, &quote!(*));
                // Fixed point: the product holds the others' integer bits,
                // shifted back exactly; its roundings, at `2^-bits` of the
                // scale, grow by `2^bits` (two per multiply, as `shifted`).
                let prod = quote!(gf * #others);
                if self.fixed && bits > 0 {
                    self.add_backward_units(2f64.powi(bits as i32 + 1), sf);
                    let bits = Literal::u32_unsuffixed(bits);
                    quote!((#prod).times_pow2(#bits))
                } else {
                    self.add_backward_units(others_len as f64, sf);
                    prod
                }
            };
            let v = self.rescale(v, scales[q] - sf, scales[q]);
            let target = self.adjoint_name(g);
            body.extend(quote!(#rt::add_all(&mut #target, #v);));
        }
        ops
    }
}
