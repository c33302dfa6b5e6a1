//! The MPE function of a block template: a max-product forward sweep that records the
//! best tuple of every block sum, then backtracking from the root.
//!
//! In scalar code one call labels one component and a best tuple is `[segment, i, j,
//! k]`. In SIMD code one call labels a lane group of components: the sweep runs on
//! lane vectors with [`Lanes::arg_max`](graphspn_runtime::__private::Lanes), each best
//! tuple packed into one lane value (an integer below 2^24, exact in `f32`), and the
//! backtracking then runs once per lane on that lane's unpacked codes. Every value is
//! computed by the same operations in the same order as in scalar code, so both forms
//! give the same labels. A template whose codes do not fit 24 bits (an input of more
//! than about 60 classes or sums) runs its scalar function once per lane instead.

use std::collections::BTreeSet;

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::super::emit::{Lit, int, join, rt};
use super::super::kernels::{Block, Plan, Segment};
use super::{SparseCode, rows};

/// Largest total width (bits) of a packed code: every code is then an integer below
/// 2^24, exact in an `f32` lane and in a 32-bit `usize`.
const CODE_BITS: u32 = 24;

/// Bits of an index below `n`.
fn bits(n: usize) -> u32 {
    match n {
        0 | 1 => 0,
        n => usize::BITS - (n - 1).leading_zeros(),
    }
}

/// The field widths of a block's packed codes, `[segment, i, j, k]` (see
/// `graphspn_runtime::__private::LaneArgs`).
fn widths(block: &Block) -> [u32; 4] {
    let mut w = [bits(block.segments.len()), 0, 0, 0];
    for seg in &block.segments {
        for (wf, &d) in w[1..].iter_mut().zip(&seg.dims) {
            *wf = (*wf).max(bits(d));
        }
    }
    w
}

/// The bit offset of field `f` (`0` segment, `1` i, `2` j, `3` k) in a packed code.
fn shift(widths: &[u32; 4], f: usize) -> u32 {
    widths[f + 1..].iter().sum()
}

/// The packed code of a tuple, `fields = [segment, i, j, k]` (missing ones 0).
fn pack(widths: &[u32; 4], fields: &[usize]) -> usize {
    fields
        .iter()
        .enumerate()
        .map(|(f, &i)| i << shift(widths, f))
        .sum()
}

/// Whether every block's codes fit [`CODE_BITS`].
fn packs(plan: &Plan) -> bool {
    plan.blocks
        .iter()
        .all(|b| widths(b).iter().sum::<u32>() <= CODE_BITS)
}

/// How the function holds its best tuples.
#[derive(Clone, Copy, PartialEq)]
enum Codes {
    /// One component per call: `[u16; 4]` per sum.
    Scalar,
    /// A lane group per call: one packed lane value per sum.
    Packed,
}

/// The literals and codes of one MPE function.
struct Form<'l> {
    l: &'l Lit,
    codes: Codes,
}

impl Form<'_> {
    /// A constant: a scalar literal, or splat over the lanes in packed form.
    fn lit(&self, x: f64) -> TokenStream {
        let v = self.l.num(x);
        match self.codes {
            Codes::Packed => quote!(V::splat(#v)),
            Codes::Scalar => v,
        }
    }

    /// The code of a constant tuple, `fields = [segment, i, j, k]` (missing ones 0).
    fn const_code(&self, w: &[u32; 4], fields: &[usize]) -> TokenStream {
        match self.codes {
            Codes::Packed => self.lit(pack(w, fields) as f64),
            Codes::Scalar => {
                let mut c: Vec<usize> = fields.to_vec();
                c.resize(4, 0);
                let c = c.into_iter().map(int);
                quote!([#(#c),*])
            }
        }
    }

    /// The code of segment `s`'s tuple of arg-maxima `ivs` (lane values in packed
    /// form, `u16` indices in scalar form).
    fn floor_code(&self, w: &[u32; 4], s: usize, ivs: &[Ident]) -> TokenStream {
        match self.codes {
            Codes::Packed => {
                let seg = self.lit(pack(w, &[s]) as f64);
                let terms = ivs.iter().enumerate().map(|(f, iv)| {
                    let m = self.lit(f64::from(1u32 << shift(w, f + 1)));
                    quote!(#iv * #m)
                });
                quote!(#seg #(+ #terms)*)
            }
            Codes::Scalar => {
                let s = int(s);
                let pad = (ivs.len()..3).map(|_| int(0));
                quote!([#s, #(#ivs,)* #(#pad),*])
            }
        }
    }
}

impl SparseCode<'_> {
    /// `fn <prefix>_mpe(x, lab) -> V`: the max-product value of each of `lanes`
    /// components (the module's SIMD lanes; 1 in scalar code) and, by backtracking the
    /// best tuple of every selected sum, its arg-max labelling into `lab[lane]`; and
    /// its multiply count per call.
    pub fn mpe(&self, l: &Lit, lanes: usize) -> (TokenStream, usize) {
        let (c, n, lanes_t) = (int(self.plan.classes), int(self.plan.n), int(lanes));
        let (name, t) = (self.ident("mpe"), l.ty());
        if lanes == 1 {
            let (body, ops) = self.mpe_body(l, Codes::Scalar);
            let f = quote!(fn #name(x: &[[#t; #c]; #n], lab: &mut [[u16; #n]; 1]) -> #t);
            return (quote!(#[inline(never)] #f { #body }), ops);
        }
        if packs(self.plan) {
            let (body, ops) = self.mpe_body(l, Codes::Packed);
            let f = quote!(fn #name(x: &[[V; #c]; #n], lab: &mut [[u16; #n]; #lanes_t]) -> V);
            return (quote!(#[inline(never)] #f { #body }), ops);
        }
        let (one, rt) = (self.ident("mpe1"), rt());
        let (body, ops) = self.mpe_body(l, Codes::Scalar);
        let code = quote!(
            #[inline(never)]
            fn #one(x: &[[#t; #c]; #n], lab: &mut [[u16; #n]; 1]) -> #t { #body }
            #[inline(never)]
            fn #name(x: &[[V; #c]; #n], lab: &mut [[u16; #n]; #lanes_t]) -> V {
                let mut r = V::ZERO;
                for (l, lab) in lab.iter_mut().enumerate() {
                    let v = #one(&#rt::lane_rows(x, l), ::core::array::from_mut(lab));
                    Lanes::set_lane(&mut r, l, v);
                }
                r
            }
        );
        (code, ops * lanes)
    }

    /// The body of an MPE function: the sweep, the backtracking (per lane in packed
    /// form) and the root value; and its multiply count.
    fn mpe_body(&self, l: &Lit, codes: Codes) -> (TokenStream, usize) {
        let f = Form { l, codes };
        let rt = rt();
        let mut ops = 0;
        let mut body = TokenStream::new();
        let mut done = BTreeSet::new();
        for (b, block) in self.plan.blocks.iter().enumerate() {
            ops += self.mpe_block(&f, b, block, &mut done, &mut body);
        }
        let mut back = TokenStream::new();
        self.backtrack(&mut back);
        if codes == Codes::Packed {
            let unpack = self.plan.blocks.iter().enumerate().map(|(b, block)| {
                let ab = format_ident!("a{b}");
                let w = widths(block).map(Literal::u32_unsuffixed);
                quote!(let #ab = #rt::LaneArgs { codes: &#ab, lane: l, widths: [#(#w),*] };)
            });
            body.extend(quote!(for (l, lab) in lab.iter_mut().enumerate() { #(#unpack)* #back }));
        } else {
            body.extend(quote!({ let lab = &mut lab[0]; #back }));
        }
        body.extend(self.root());
        (body, ops)
    }

    /// The sweep of block `b`: its values `b{b}` and best tuples `a{b}`; returns the
    /// multiply count.
    fn mpe_block(
        &self,
        f: &Form,
        b: usize,
        block: &Block,
        done: &mut BTreeSet<usize>,
        body: &mut TokenStream,
    ) -> usize {
        let rt = rt();
        let (bb, ab) = (format_ident!("b{b}"), format_ident!("a{b}"));
        let (m_len, zero, minus_one) = (int(block.sums.len()), f.lit(0.0), f.lit(-1.0));
        let args = match f.codes {
            Codes::Packed => quote!([V::ZERO; #m_len]),
            Codes::Scalar => quote!([[0u16; 4]; #m_len]),
        };
        body.extend(quote!(let mut #bb = [#zero; #m_len]; let mut #ab = #args;));
        let w = widths(block);
        let seg_rows: Vec<_> = block.segments.iter().map(rows).collect();
        for (s, (seg, sr)) in block.segments.iter().zip(&seg_rows).enumerate() {
            if sr.iter().any(|r| r.floor > 0.0) {
                self.floor_term(f, (b, s), seg, &w, done, body);
            }
        }
        let mut ops = 0;
        // Row `m` gathers its candidates from every segment (`seg_rows[s][m]`).
        for m in 0..block.sums.len() {
            let mi = int(m);
            body.extend(quote!(let mut r = #minus_one;));
            for (s, (seg, sr)) in block.segments.iter().zip(&seg_rows).enumerate() {
                let row = &sr[m];
                let mut cand = |value: TokenStream, code: TokenStream| {
                    ops += seg.inputs.len();
                    body.extend(match f.codes {
                        Codes::Packed => quote!(V::arg_max(&mut r, &mut #ab[#mi], #value, #code);),
                        Codes::Scalar => quote!(#rt::sel(&mut r, &mut #ab[#mi], #value, #code);),
                    });
                };
                if row.floor > 0.0 {
                    let (fp, fc) = (format_ident!("fp{b}_{s}"), format_ident!("fc{b}_{s}"));
                    let floor = f.lit(row.floor);
                    cand(quote!(#fp * #floor), quote!(#fc));
                }
                for &(tt, _, wt) in &row.above {
                    let idx = seg.tuple(tt);
                    let p = join(
                        seg.inputs.iter().zip(&idx).map(|(&g, &i)| self.elem(g, i)),
                        &quote!(*),
                    );
                    let mut fields = vec![s];
                    fields.extend(&idx);
                    let wt = f.lit(wt);
                    cand(quote!(#p * #wt), f.const_code(&w, &fields));
                }
            }
            body.extend(quote!(#bb[#mi] = Lanes::max(r, #zero);));
        }
        ops
    }

    /// The floor term of segment `s` of block `b`, shared by its rows: the product of
    /// the inputs' maxima `fp{b}_{s}` and the code of their arg-maxima `fc{b}_{s}`
    /// (each input's `mv{g}` / `iv{g}` bound on first use).
    fn floor_term(
        &self,
        f: &Form,
        (b, s): (usize, usize),
        seg: &Segment,
        w: &[u32; 4],
        done: &mut BTreeSet<usize>,
        body: &mut TokenStream,
    ) {
        let rt = rt();
        for &g in &seg.inputs {
            if done.insert(g) {
                let (mv, iv, v) = (
                    format_ident!("mv{g}"),
                    format_ident!("iv{g}"),
                    self.vec_name(g),
                );
                body.extend(match f.codes {
                    Codes::Packed => quote!(let (#mv, #iv) = #rt::amax_lanes(&#v);),
                    Codes::Scalar => quote!(let (#mv, #iv) = #rt::amax(&#v);),
                });
            }
        }
        let (fp, fc) = (format_ident!("fp{b}_{s}"), format_ident!("fc{b}_{s}"));
        let p = join(
            seg.inputs.iter().map(|g| format_ident!("mv{g}")),
            &quote!(*),
        );
        let ivs: Vec<_> = seg.inputs.iter().map(|g| format_ident!("iv{g}")).collect();
        let c = f.floor_code(w, s, &ivs);
        body.extend(quote!(let #fp = #p; let #fc = #c;));
    }

    /// MPE backtracking: from the root, mark the selected tuple of every selected
    /// sum, then write each variable's selected class into `lab`.
    fn backtrack(&self, body: &mut TokenStream) {
        let p = self.plan;
        let rt = rt();
        let c = int(p.classes);
        for v in 0..p.n {
            let sx = format_ident!("sx{v}");
            body.extend(quote!(let mut #sx = [false; #c];));
        }
        for (b, block) in p.blocks.iter().enumerate() {
            let sb = format_ident!("s{b}");
            let len = int(block.sums.len());
            body.extend(quote!(let mut #sb = [false; #len];));
        }
        let (s_root, m_root) = (format_ident!("s{}", p.root.0), int(p.root.1));
        body.extend(quote!(#s_root[#m_root] = true;));
        for (b, block) in p.blocks.iter().enumerate().rev() {
            let (sb, ab) = (format_ident!("s{b}"), format_ident!("a{b}"));
            for (s, seg) in block.segments.iter().enumerate() {
                let sels = join(
                    seg.inputs.iter().map(|&g| {
                        let sel = if g < p.n {
                            format_ident!("sx{g}")
                        } else {
                            format_ident!("s{}", g - p.n)
                        };
                        quote!(&mut #sel)
                    }),
                    &quote!(,),
                );
                let back = format_ident!("d{}_back", seg.dims.len());
                let s = int(s);
                body.extend(quote!(#rt::#back(#s, &#sb, &#ab, #sels);));
            }
        }
        for v in 0..p.n {
            let (sx, vi) = (format_ident!("sx{v}"), int(v));
            body.extend(quote!(#rt::sel_label(&#sx, &mut lab[#vi]);));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codegen::kernels::{Segment, plan};
    use crate::learn::{DenseParams, symmetric_dense_structure};
    use crate::template::Template;
    use graphspn_runtime::__private::{Args, LaneArgs};
    use wide::f32x8;

    /// A block of one sum over `segs` (each a list of input lengths), weights 1.
    fn block(segs: &[&[usize]]) -> Block {
        Block {
            sums: vec![0],
            segments: segs
                .iter()
                .map(|dims| Segment {
                    inputs: (0..dims.len()).collect(),
                    dims: dims.to_vec(),
                    weights: vec![vec![1.0; dims.iter().product()]],
                })
                .collect(),
        }
    }

    #[test]
    fn index_bits() {
        let b: Vec<u32> = [0, 1, 2, 3, 4, 5, 10, 16, 17, 64, 65].map(bits).to_vec();
        assert_eq!(b, [0, 0, 1, 2, 2, 3, 4, 4, 5, 6, 7]);
        assert_eq!(widths(&block(&[&[10, 5], &[3, 3, 9]])), [1, 4, 3, 4]);
    }

    /// Every tuple of every segment of the learned Star's plan packs into an `f32`
    /// exactly and unpacks, in any lane, to its fields; the codes are distinct.
    #[test]
    fn star_codes_round_trip_through_the_runtime() {
        let spn = symmetric_dense_structure(
            5,
            10,
            &DenseParams::default(),
            &Template::star().automorphisms(),
            3,
        )
        .unwrap();
        let p = plan(&spn, 10).expect("plan");
        assert!(packs(&p));
        for b in &p.blocks {
            let w = widths(b);
            let mut seen = std::collections::BTreeSet::new();
            for (s, seg) in b.segments.iter().enumerate() {
                for t in 0..seg.dims.iter().product() {
                    let mut fields = vec![s];
                    fields.extend(seg.tuple(t));
                    let code = pack(&w, &fields);
                    assert!(code < 1 << CODE_BITS && seen.insert(code));
                    let mut lanes = [0.0f32; 8];
                    lanes[3] = code as f32;
                    let codes = [f32x8::from(lanes)];
                    let got = LaneArgs {
                        codes: &codes,
                        lane: 3,
                        widths: w,
                    }
                    .arg(0);
                    fields.resize(4, 0);
                    let want: Vec<u16> = fields.iter().map(|&f| f as u16).collect();
                    assert_eq!(got.to_vec(), want, "block tuple {t} of segment {s}");
                }
            }
        }
    }

    /// A block whose codes need more than 24 bits is not packed: its SIMD MPE function
    /// runs the scalar one per lane.
    #[test]
    fn too_wide_codes_fall_back_to_the_scalar_function_per_lane() {
        let wide = Plan {
            n: 2,
            classes: 4096,
            blocks: vec![block(&[&[4096, 2], &[2, 4096]])],
            root: (0, 0),
        };
        assert_eq!(widths(&wide.blocks[0]), [1, 12, 12, 0]);
        assert!(!packs(&wide));
        let l = Lit::new(crate::codegen::Precision::F32);
        let simd = SparseCode::float("t".into(), &wide)
            .mpe(&l, 8)
            .0
            .to_string();
        assert!(simd.contains("fn t_mpe1") && simd.contains("lane_rows"));
        let scalar = SparseCode::float("t".into(), &wide)
            .mpe(&l, 1)
            .0
            .to_string();
        assert!(!scalar.contains("t_mpe1") && !scalar.contains("LaneArgs"));
        let narrow = Plan {
            blocks: vec![block(&[&[64, 2], &[2, 64]])],
            classes: 64,
            ..wide
        };
        let simd = SparseCode::float("t".into(), &narrow)
            .mpe(&l, 8)
            .0
            .to_string();
        assert!(!simd.contains("t_mpe1") && simd.contains("LaneArgs"));
    }
}
