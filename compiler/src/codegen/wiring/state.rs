//! The streaming `State` of the generated module: a caller-owned cache of every
//! component's value and local posteriors, updated one place at a time.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use super::super::analysis::Numerics;
use super::super::emit::{int, rt};
use super::{Context, Tpl, component_int, lane_vector};

/// The `State` type, its constructor and its methods.
pub(super) fn state_api(tpls: &[Tpl], cx: &Context) -> TokenStream {
    let table = cx.simd_lanes > 1;
    let ty = state_type(cx, table);
    let cache = cache_methods(tpls, cx, table);
    // Log-space templates (a one-hot assignment of value 0) read every normal entry of
    // a fused row: a class flushed to 0 there could make the likelihood 0.
    let log_space = tpls.iter().any(|t| t.numerics == Numerics::Log);
    let updates = update_methods(cx, table, log_space);
    let queries = query_methods(tpls, cx);
    let rt = rt();
    let new_table = if table {
        quote! {
            scaled: [[0.0; NUM_CLASSES]; NUM_PLACES],
            dpost: [[[0.0; NUM_CLASSES]; NUM_PLACES]; NUM_DECOMPOSITIONS],
        }
    } else {
        quote!(post: [[0.0; NUM_CLASSES]; NUM_ROWS],)
    };
    let chunks = int(tpls.iter().map(value_chunks).sum::<usize>().max(1));
    quote! {
        /// Partial products of the streaming state: chunks of `VALUE_CHUNK` components.
        const NUM_VALUE_CHUNKS: usize = #chunks;
        #ty
        impl State {
            /// A state with no evidence at any place (all zeros in memory: rows of ones are
            /// written by the first call that needs them).
            pub const fn new() -> State {
                State {
                    ev: [[0.0; NUM_CLASSES]; NUM_PLACES],
                    #new_table
                    lns: [0.0; NUM_PLACES],
                    fused: [#rt::Fused::ZERO; NUM_PLACES],
                    shift: 0,
                    val: [0.0; NUM_COMPONENTS],
                    parts: [[#rt::Acc::ZERO; NUM_DECOMPOSITIONS]; NUM_VALUE_CHUNKS],
                    w: [0.0; NUM_DECOMPOSITIONS],
                    lhat: 0.0,
                    ok: false,
                    ready: false,
                }
            }

            /// The current evidence rows (all ones where a place has none; a row fused by
            /// `observe` is the product of the place's observations scaled by a power of two,
            /// largest entry in `[1, 2)`, classes below `2^-24` of it (`f32`; `2^-200` in `f64`)
            /// set to 0: a GraphSPN template multiplies up to five entries, whose products
            /// must stay normal).
            pub fn evidence(&self) -> &Evidence {
                if self.ready { &self.ev } else { &NO_EVIDENCE }
            }

            #cache
            #updates
            #queries
        }
    }
}

/// The `State` struct (with its documentation), `NO_EVIDENCE` and `Default`; `table`:
/// the state also keeps every row scaled (SIMD hosts: lane groups are then gathered by
/// loads and a transpose).
fn state_type(cx: &Context, table: bool) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let table_field = if table {
        quote! {
            /// Every row of `ev` scaled to a largest entry of 1 (what the gathers read).
            scaled: Evidence,
            /// Every place's local posterior row per decomposition, `dpost[d][place]`
            /// (where updates store the components' posteriors: `marginals` then mixes
            /// contiguous memory).
            dpost: [[[#t; NUM_CLASSES]; NUM_PLACES]; NUM_DECOMPOSITIONS],
        }
    } else {
        quote! {
            /// Every component's local posterior rows (`NUM_ROWS`, see `PLACE_SLOTS`).
            post: [[#t; NUM_CLASSES]; NUM_ROWS],
        }
    };
    quote! {
        /// Streaming inference for a robot that gets evidence one place at a time: the
        /// caller-owned cache of every component's value and local posteriors (fixed size,
        /// [`STATE_BYTES`] bytes, nothing on the heap; `const` constructor, so it can live in a
        /// `static` or `.bss`).
        ///
        /// An update (`set_evidence`, `observe`, `clear_evidence`) re-evaluates only the
        /// components containing that place (at most one per decomposition) and re-mixes the
        /// decompositions from the cached component values (partial products of 16 values,
        /// recomputed where a value changed; never by dividing or subtracting, so a million
        /// updates do not drift). `observe` keeps each class's product of
        /// observations as a mantissa and a binary exponent per class, one rounding per
        /// observation and class (relative `ε/2`: after `n` observations at most about
        /// `n·ε/2`, typically `√n·ε/2`): no class underflows, none is locked out however
        /// many observations arrive, and `log_likelihood` is that of the product of every
        /// observation (to those roundings). Costs: an update, about
        /// [`MACS_OBSERVE_MARGINALS`] multiply-adds with `marginals`; `log_likelihood` one
        /// addition per place (their rows' scales), `marginal` O(D·C); `marginals`
        /// O(places·D·C); `mpe` and
        /// `labelled_log_likelihood` a full stateless pass on the state's evidence. The first
        /// call after [`State::new`] evaluates every component once. [`State::new`] is all
        /// zeros, so a `static` state is placed in `.bss` (no initial image in flash).
        /// No evidence at a place means a row of ones.
        #[derive(Clone)]
        pub struct State {
            ev: Evidence,
            #table_field
            lns: [#t; NUM_PLACES],
            fused: [#rt::Fused<#t, NUM_CLASSES>; NUM_PLACES],
            /// `Σ fused[q].shift()` over the places (what `ln_scale` reads).
            shift: i64,
            val: [#t; NUM_COMPONENTS],
            parts: [[#rt::Acc<#t>; NUM_DECOMPOSITIONS]; NUM_VALUE_CHUNKS],
            w: [#t; NUM_DECOMPOSITIONS],
            lhat: #t,
            ok: bool,
            ready: bool,
        }

        /// The rows of a state without any evidence.
        const NO_EVIDENCE: Evidence = [[1.0; NUM_CLASSES]; NUM_PLACES];

        impl Default for State {
            fn default() -> Self {
                Self::new()
            }
        }
    }
}

/// The number of partial products a template's components take in the `State`
/// (`VALUE_CHUNK` components each, see `graphspn_runtime::__private::chunk_values`).
pub(super) fn value_chunks(tp: &Tpl) -> usize {
    tp.members
        .len()
        .div_ceil(graphspn_runtime::__private::VALUE_CHUNK)
}

/// Per template: the component values held in `val` (the cache's layout) multiplied
/// into the decomposition accumulators `acc` (shared by the `State` and the one-pass
/// stateless `marginals`).
pub(super) fn cached_values(tpls: &[Tpl], val: &TokenStream) -> TokenStream {
    let rt = rt();
    tpls.iter()
        .map(|tp| {
            let (stat, first_component) = (&tp.stat, int(tp.first_component));
            quote!(if let Some(v) = #val.get(#first_component..) { #rt::state_values(&#stat, v, &mut acc); })
        })
        .collect()
}

/// Per template: the local posteriors held in `post` (the cache's layout), weighted by
/// the decomposition weights `w`, added into `out`.
pub(super) fn cached_marginals(tpls: &[Tpl], post: &TokenStream, w: &TokenStream) -> TokenStream {
    let rt = rt();
    tpls.iter()
        .map(|tp| {
            let (stat, first_row) = (&tp.stat, int(tp.first_row));
            quote!(if let Some(p) = #post.get(#first_row..) { #rt::state_marginals(&#stat, p, &#w, out); })
        })
        .collect()
}

/// What the cache methods do with the scaled evidence rows only SIMD hosts keep
/// (`table`, see [`state_type`]).
struct HostTables {
    /// The gathers' source of scaled rows (`None` without the table).
    source: TokenStream,
    /// A fresh state's scaled rows.
    fresh_table: TokenStream,
    /// Storing `row` for `place` into the scaled rows.
    store_table: TokenStream,
}

/// [`HostTables`]: code for SIMD hosts (`table`), nothing otherwise.
fn host_tables(table: bool) -> HostTables {
    let rt = rt();
    if !table {
        return HostTables {
            source: quote!(None),
            fresh_table: TokenStream::new(),
            store_table: TokenStream::new(),
        };
    }
    HostTables {
        source: quote!(Some(&self.scaled)),
        fresh_table: quote!(self.scaled = NO_EVIDENCE;),
        store_table: quote! {
            if let Some(s) = self.scaled.get_mut(place) {
                *s = #rt::scale_row(&row);
            }
        },
    }
}

/// The cache's private methods: evaluating one lane group of a template, one unit
/// (global group), re-mixing the decompositions, refreshing everything, storing a row.
fn cache_methods(tpls: &[Tpl], cx: &Context, table: bool) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let HostTables {
        source,
        fresh_table,
        store_table,
    } = host_tables(table);
    let (comp_t, _) = component_int(tpls.iter().map(|tp| tp.members.len()).sum());
    let mut eval_fns = TokenStream::new();
    let mut update = TokenStream::new();
    let mut refresh = TokenStream::new();
    let mut first_chunk = 0;
    for (ti, tp) in tpls.iter().enumerate() {
        let chunks = value_chunks(tp);
        let (chunk0, chunk_end) = (int(first_chunk), int(first_chunk + chunks));
        first_chunk += chunks;
        let (f, stat) = (tp.eval_group(ti), &tp.stat);
        let (first_component, first_row) = (int(tp.first_component), int(tp.first_row));
        let groups = int(tp.groups());
        let fc = format_ident!("{f}_components");
        // Where the components' local posteriors go: the SIMD host's rows per
        // decomposition, or this template's rows of the component cache.
        let rows = if table {
            quote!(Some(&mut self.dpost))
        } else {
            quote!(self.post.get_mut(#first_row..))
        };
        eval_fns.extend(quote! {
            #[inline(never)] fn #f(&mut self, g: usize) { if let (Some(v), Some(p)) = (self.val.get_mut(#first_component..), #rows) { #rt::eval_group(&#stat, &self.ev, #source, g, v, p); } }
            #[inline(never)] fn #fc(&mut self, comps: &[#comp_t]) {
                if let (Some(v), Some(p)) = (self.val.get_mut(#first_component..), #rows) { #rt::eval_components(&#stat, &self.ev, #source, comps, #first_component, v, p); }
                if let (Some(v), Some(ps)) = (self.val.get(#first_component..), self.parts.get_mut(#chunk0..#chunk_end)) { #rt::update_chunks(&#stat, comps, #first_component, v, ps); }
            }
        });
        update.extend(quote!(self.#fc(comps);));
        refresh.extend(quote! {
            for g in 0..#groups { self.#f(g); }
            if let (Some(v), Some(ps)) = (self.val.get(#first_component..), self.parts.get_mut(#chunk0..#chunk_end)) { #rt::chunk_values(&#stat, v, ps); }
        });
    }
    quote! {
        #eval_fns

        /// Re-evaluates the components `comps` (global indices, see `PLACE_COMPONENTS`).
        fn eval_components(&mut self, comps: &[#comp_t]) {
            #update
        }

        /// Re-mixes the decompositions from the cached partial products.
        fn remix(&mut self) {
            let mut acc = [#rt::Acc::ONE; NUM_DECOMPOSITIONS];
            #rt::combine_chunks(&self.parts, &mut acc);
            match #rt::mix(&acc) {
                Some((l, w)) => {
                    self.lhat = l;
                    self.w = w;
                    self.ok = true;
                }
                None => self.ok = false,
            }
        }

        /// Evaluates every component (after `set_all`, or on the first use of a new state).
        fn refresh(&mut self) {
            #refresh
            self.remix();
            self.ready = true;
        }

        /// A new state gets its rows of ones and every component evaluated.
        fn fresh(&mut self) {
            if !self.ready {
                self.ev = NO_EVIDENCE;
                #fresh_table
                self.lns = [0.0; NUM_PLACES];
                self.fused = [#rt::Fused::ONES; NUM_PLACES];
                self.shift = 0;
                self.refresh();
            }
        }

        /// Stores `row` and its fused form for `place` and re-evaluates the components
        /// containing it.
        fn store(&mut self, place: usize, row: [#t; NUM_CLASSES], fused: #rt::Fused<#t, NUM_CLASSES>) {
            self.fresh();
            if let (Some(r), Some(s), Some(f)) = (self.ev.get_mut(place), self.lns.get_mut(place), self.fused.get_mut(place)) {
                *r = row;
                *s = #rt::Real::ln(row.iter().copied().fold(0.0, #t::max));
                self.shift += i64::from(fused.shift()) - i64::from(f.shift());
                *f = fused;
            }
            #store_table
            if let Some(comps) = PLACE_COMPONENTS.get(place) {
                self.eval_components(comps);
            }
            self.remix();
        }
    }
}

/// The evidence updates: `set_evidence`, `observe`, `clear_evidence`, `set_all`
/// (`table`: the state keeps scaled rows, see [`state_type`]; `log_space`: some
/// template computes in log space, so `observe` keeps every normal entry of a fused row
/// rather than flushing those below `2^PRODUCT_FLUSH_EXP` of the best class).
fn update_methods(cx: &Context, table: bool, log_space: bool) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let flush = if log_space {
        quote!(MIN_EXP)
    } else {
        quote!(PRODUCT_FLUSH_EXP)
    };
    let set_all_table = if table {
        quote!(#rt::scale_rows(&self.ev, None, &mut self.scaled);)
    } else {
        TokenStream::new()
    };
    let check = cx.l.helper("check");
    let err = quote!(::graphspn_runtime::EvidenceError);
    quote! {
        fn place_index(place: usize) -> Result<u32, #err> {
            PLACE_IDS.get(place).copied().ok_or(::graphspn_runtime::EvidenceError::PlaceOutOfRange { place, places: NUM_PLACES })
        }

        /// Sets the evidence row of `place` (place index) and updates the cache. An invalid
        /// row (NaN, infinite, negative, all zero) is rejected and nothing changes.
        pub fn set_evidence(&mut self, place: usize, row: &[#t; NUM_CLASSES]) -> Result<(), #err> {
            let id = Self::place_index(place)?;
            #rt::check_row(row, place, id)?;
            self.store(place, *row, #rt::Fused::of(row));
            Ok(())
        }

        /// Fuses a new observation into the place's row (element-wise product, one
        /// rounding per class, so repeated observations never underflow) and updates the
        /// cache. An invalid row, or one that leaves the place no class at all, is
        /// rejected and nothing changes.
        pub fn observe(&mut self, place: usize, row: &[#t; NUM_CLASSES]) -> Result<(), #err> {
            let id = Self::place_index(place)?;
            #rt::check_row(row, place, id)?;
            self.fresh();
            let old = match self.fused.get(place) {
                Some(f) => *f,
                None => #rt::Fused::ONES,
            };
            match old.observe(row, <#t as #rt::Real>::#flush) {
                Some((f, r)) => {
                    self.store(place, r, f);
                    Ok(())
                }
                None => Err(::graphspn_runtime::EvidenceError::NoMass { place, place_id: u64::from(id) }),
            }
        }

        /// Removes the evidence of `place` (back to a row of ones) and updates the cache.
        pub fn clear_evidence(&mut self, place: usize) -> Result<(), #err> {
            Self::place_index(place)?;
            self.store(place, [1.0; NUM_CLASSES], #rt::Fused::ONES);
            Ok(())
        }

        /// Replaces all evidence and re-evaluates every component.
        pub fn set_all(&mut self, e: &Evidence) -> Result<(), #err> {
            #check(e, &PLACE_IDS)?;
            self.ev = *e;
            #set_all_table
            for ((s, f), row) in self.lns.iter_mut().zip(self.fused.iter_mut()).zip(e) {
                *s = #rt::Real::ln(row.iter().copied().fold(0.0, #t::max));
                *f = #rt::Fused::of(row);
            }
            self.shift = #rt::shift_sum(&self.fused);
            self.refresh();
            Ok(())
        }
    }
}

/// The queries answered from the cache (`log_likelihood`, `marginals`, `marginal`) or
/// by a stateless pass on the state's evidence (`mpe`, `labelled_log_likelihood`).
fn query_methods(tpls: &[Tpl], cx: &Context) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    // Each place mixes its D posterior rows: rows of contiguous multiply-adds (SIMD
    // hosts: 0.6 µs less per step at 230 places; Cortex-M4F: 4% fewer instructions).
    // Without an FPU (the fixed-point kernel's targets) each cached component's rows
    // are added once instead, weighted by all its decompositions (a component shared
    // by several decompositions costs one row), in Q1.31 integer multiply-adds: the
    // soft-float mix was three quarters of a Cortex-M3 step.
    let simd = cx.simd_lanes > 1;
    let mix = if simd {
        let (v, lanes) = (lane_vector(cx), int(cx.simd_lanes));
        quote!(#rt::mix_decompositions::<#v, #lanes, NUM_CLASSES, NUM_PLACES, NUM_DECOMPOSITIONS>(&self.dpost, &self.w, out);)
    } else if !cx.fixed {
        quote!(#rt::mix_places(&self.post, &PLACE_SLOTS, &self.w, out);)
    } else {
        let calls: TokenStream = tpls
            .iter()
            .map(|tp| {
                let (stat, first_row) = (&tp.stat, int(tp.first_row));
                quote!(if let Some(p) = self.post.get(#first_row..) { #rt::state_marginals_fx(&#stat, p, &wq, out); })
            })
            .collect();
        quote! {
            let wq = #rt::fx_weights(&self.w);
            for row in out.iter_mut() {
                *row = [0.0; NUM_CLASSES];
            }
            #calls
            #rt::fx_finish_rows(out);
        }
    };
    let mix_one = if simd {
        quote!(#rt::mix_place(&self.dpost, &self.w, place, row);)
    } else {
        quote! {
            if let Some(slots) = PLACE_SLOTS.get(place) {
                #rt::mix_rows(&self.post, slots, &self.w, row);
            }
        }
    };
    let err = quote!(::graphspn_runtime::EvidenceError);
    quote! {
        /// Natural log of the likelihood of the current evidence (from the cache): of the
        /// product of every observation where rows were fused by `observe`.
        pub fn log_likelihood(&mut self) -> Result<#t, #err> {
            self.fresh();
            let scale: #t = #rt::ln_scale(&self.lns, self.shift);
            if self.ok && scale + self.lhat > #t::NEG_INFINITY {
                Ok(scale + self.lhat)
            } else {
                Err(::graphspn_runtime::EvidenceError::ZeroLikelihood)
            }
        }

        /// Writes the marginals of every place into `out` from the cache and returns the
        /// log-likelihood.
        pub fn marginals(&mut self, out: &mut Marginals) -> Result<#t, #err> {
            let l = self.log_likelihood()?;
            #mix
            Ok(l)
        }

        /// Writes the marginal of one place into `row` (O(D·C) from the cache).
        pub fn marginal(&mut self, place: usize, row: &mut [#t; NUM_CLASSES]) -> Result<(), #err> {
            Self::place_index(place)?;
            self.log_likelihood()?;
            #mix_one
            Ok(())
        }

        /// The MPE labelling of the current evidence and its log value (a full max-product
        /// pass; the value is of the product of every observation, like `log_likelihood`).
        pub fn mpe(&mut self, labels: &mut Labels) -> Result<#t, #err> {
            Ok(mpe_unchecked(self.evidence(), labels)? + #rt::shift_ln::<#t>(self.shift))
        }

        /// The log-likelihood of the current evidence with labelled places restricted to
        /// their labels (a full value pass; of the product of every observation, like
        /// `log_likelihood`; a label that a fused row reads as 0, below `2^-24` of the
        /// place's best class, counts with its exact fused value).
        pub fn labelled_log_likelihood(&mut self, labels: &Labels) -> Result<#t, #err> {
            #rt::check_labels(labels, NUM_CLASSES)?;
            let e = self.evidence();
            let scale = #rt::fused_log_scale(e, &self.fused, labels);
            Ok(labelled_scaled(labels, e, scale)? + #rt::shift_ln::<#t>(self.shift))
        }
    }
}
