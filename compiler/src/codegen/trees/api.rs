//! The public functions of a tree-mixture module: the stateless entry points (each a
//! call into `graphspn_runtime::__private::tree` with the module's `MODEL`) and the
//! streaming `State`.

use proc_macro2::TokenStream;
use quote::quote;

use super::super::emit::rt;
use super::super::surface::{checked, checked_labelled};
use super::plan::Context;

/// The driver's generic arguments: lane vector, classes, row vectors, places, stack
/// rows, trees.
fn generics() -> TokenStream {
    quote!(::<V, NUM_CLASSES, K, NUM_PLACES, H, NUM_TREES>)
}

/// The sentences `log_likelihood` and `marginals` add when the messages are in fixed
/// point (`message_error`: each entry within `η` of itself, relative): the bounds
/// `n·η` nats and `4n·η` with this module's numbers. None otherwise.
fn fixed_accuracy(places: usize, message_error: Option<f64>) -> (Option<String>, Option<String>) {
    let Some(eta) = message_error else {
        return (None, None);
    };
    let n = places as f64;
    // lint: the bound's numbers are this module's, part of a doc comment.
    let ll = format!(
        " Messages `ψ·b` in fixed point: each entry within `η` = {eta:.1e} of itself, so at most `n·η` = {:.1e} nats more (a loose worst case).",
        n * eta
    );
    // lint: the bound's numbers are this module's, part of a doc comment.
    let marginals = format!(
        " Messages `ψ·b` in fixed point: each entry within `η` = {eta:.1e} of itself, so a marginal within `4n·η` = {:.1e} more (a loose worst case).",
        4.0 * n * eta
    );
    (Some(ll), Some(marginals))
}

/// `log_likelihood`, `labelled_log_likelihood`, `marginals`, `mpe` and their
/// `_unchecked` twins.
pub(super) fn stateless_api(cx: &Context, message_error: Option<f64>) -> TokenStream {
    let (rt, t, g) = (rt(), cx.l.ty(), generics());
    let err = quote!(::graphspn_runtime::EvidenceError);
    let (fixed_ll, fixed_marginals) = fixed_accuracy(cx.n, message_error);
    let mut ll_doc = vec![
        " Natural log of the likelihood `S(α) = Σ_y P(y) Π_v α_v(y_v)^γ` of the evidence",
        " (relative error a few `ε` per place: one rounding per multiply-add, every",
        " product kept with an exact power-of-two exponent).",
    ];
    ll_doc.extend(fixed_ll.as_deref());
    let log_likelihood = checked(
        &cx.l,
        &ll_doc,
        "log_likelihood",
        quote!(e: &Evidence),
        quote!(e),
        TokenStream::new(),
    );
    let labelled = checked_labelled(&cx.l);
    let mut marginals_doc = vec![
        " Writes the marginals `P(Y_p = c | α)` of every place into `out` (absolute error",
        " about 1e-6 in `f32`), mixed over the trees as the model says (`AVERAGE_MIXING`),",
        " and returns `ln S(α)`. Per tree an upward and a downward pass; [`State`] caches the",
        " upward messages instead.",
    ];
    marginals_doc.extend(fixed_marginals.as_deref());
    let marginals = checked(
        &cx.l,
        &marginals_doc,
        "marginals",
        quote!(e: &Evidence, out: &mut Marginals),
        quote!(e, out),
        TokenStream::new(),
    );
    let mpe = checked(
        &cx.l,
        &[
            " Writes the labelling of the most probable `(tree, labelling)` pair into `labels`",
            " and returns its natural-log value `max_t max_y ln((1/T) P_t(y) Π_v α_v(y_v)^γ)`",
            " (ties: the first tree, then the smallest class).",
        ],
        "mpe",
        quote!(e: &Evidence, labels: &mut Labels),
        quote!(e, labels),
        TokenStream::new(),
    );
    quote! {
        /// Natural log of the likelihood `S(α)` of the evidence, without validating it.
        /// Invalid evidence gives unspecified numbers (never a panic).
        pub fn log_likelihood_unchecked(e: &Evidence) -> Result<#t, #err> {
            #rt::tree_log_likelihood #g (&MODEL, e, &ALL_UNKNOWN)
        }

        #log_likelihood

        /// Like [`labelled_log_likelihood`], without validating evidence or labels.
        pub fn labelled_log_likelihood_unchecked(labels: &Labels, e: &Evidence) -> Result<#t, #err> {
            #rt::tree_log_likelihood #g (&MODEL, e, labels)
        }

        #labelled

        /// Like [`marginals`], without validating the evidence.
        pub fn marginals_unchecked(e: &Evidence, out: &mut Marginals) -> Result<#t, #err> {
            #rt::tree_marginals #g (&MODEL, e, out)
        }

        #marginals

        /// Like [`mpe`], without validating the evidence.
        pub fn mpe_unchecked(e: &Evidence, labels: &mut Labels) -> Result<#t, #err> {
            #rt::tree_mpe #g (&MODEL, e, labels)
        }

        #mpe
    }
}

/// The `State` type (a wrapper of the runtime's `TreeState`) and its methods.
pub(super) fn state_api(cx: &Context) -> TokenStream {
    let (rt, t) = (rt(), cx.l.ty());
    let err = quote!(::graphspn_runtime::EvidenceError);
    quote! {
        /// Streaming inference for a robot that gets evidence one place at a time: the
        /// caller-owned cache of every tree's upward messages and of each place's fused
        /// observations ([`STATE_BYTES`] bytes, nothing on the heap; `const` constructor, all
        /// zeros, so a `static` state sits in `.bss`). No evidence at a place means a row of
        /// ones.
        ///
        /// An update (`set_evidence`, `observe`, `clear_evidence`) recomputes the place's path
        /// to the root in every tree (messages recomputed, never divided out: no drift).
        /// `observe` keeps each class's product of observations as a mantissa and a binary
        /// exponent (one rounding per observation and class, relative `ε/2`: no class
        /// underflows or is locked out), and `log_likelihood` is that of the product of every
        /// observation. Costs: an update `Σ_t (depth_t(place) + 1)` beliefs and
        /// matrix–vector products; `log_likelihood` O(trees · classes); `marginal(place)` a
        /// walk from each root to the place; `marginals` one downward pass per tree; `mpe`
        /// and `labelled_log_likelihood` a stateless pass on the state's evidence.
        #[derive(Clone, Default)]
        pub struct State(#rt::TreeState<V, NUM_CLASSES, K, NUM_PLACES, NUM_TREES>);

        /// The rows of a state without any evidence.
        const NO_EVIDENCE: Evidence = [[1.0; NUM_CLASSES]; NUM_PLACES];

        impl State {
            /// A state with no evidence at any place (all zeros in memory: rows of ones are
            /// written by the first call that needs them).
            pub const fn new() -> State {
                State(#rt::TreeState::new())
            }

            /// The current evidence rows (all ones where a place has none; a row fused by
            /// `observe` is the product of the place's observations scaled by a power of two,
            /// largest entry in `[1, 2)`, classes below the smallest normal value times it
            /// set to 0).
            pub fn evidence(&self) -> &Evidence {
                if self.0.is_ready() { self.0.rows() } else { &NO_EVIDENCE }
            }

            /// Sets the evidence row of `place` (place index; kept as given) and updates the
            /// cache. An invalid row (NaN, infinite, negative, all zero) is rejected and
            /// nothing changes.
            pub fn set_evidence(&mut self, place: usize, row: &[#t; NUM_CLASSES]) -> Result<(), #err> {
                self.0.set_evidence(&MODEL, &PLACE_IDS, place, row)
            }

            /// Fuses a new observation into the place's row (element-wise product, one
            /// rounding per class) and updates the cache. An invalid row, or one that leaves
            /// the place no class at all, is rejected and nothing changes.
            pub fn observe(&mut self, place: usize, row: &[#t; NUM_CLASSES]) -> Result<(), #err> {
                self.0.observe(&MODEL, &PLACE_IDS, place, row)
            }

            /// Removes the evidence of `place` (back to a row of ones) and updates the cache.
            pub fn clear_evidence(&mut self, place: usize) -> Result<(), #err> {
                self.0.clear_evidence(&MODEL, &PLACE_IDS, place)
            }

            /// Replaces all evidence (validated first) and re-evaluates every tree.
            pub fn set_all(&mut self, e: &Evidence) -> Result<(), #err> {
                self.0.set_all(&MODEL, &PLACE_IDS, e)
            }

            /// Natural log of the likelihood of the current evidence (from the cache): of the
            /// product of every observation where rows were fused by `observe`.
            pub fn log_likelihood(&mut self) -> Result<#t, #err> {
                self.0.log_likelihood(&MODEL)
            }

            /// Writes the marginals of every place into `out` from the cache (one downward
            /// pass per tree) and returns the log-likelihood.
            pub fn marginals(&mut self, out: &mut Marginals) -> Result<#t, #err> {
                self.0.marginals::<H>(&MODEL, out)
            }

            /// Writes the marginal of one place into `row` (from the cache: each tree walked
            /// from its root down to the place).
            pub fn marginal(&mut self, place: usize, row: &mut [#t; NUM_CLASSES]) -> Result<(), #err> {
                self.0.marginal::<H>(&MODEL, &PLACE_IDS, place, row)
            }

            /// The MPE labelling of the current evidence and its log value (a full
            /// max-product pass; the value is of the product of every observation, like
            /// `log_likelihood`).
            pub fn mpe(&mut self, labels: &mut Labels) -> Result<#t, #err> {
                Ok(mpe_unchecked(self.evidence(), labels)? + self.0.ln_shift(&MODEL))
            }

            /// The log-likelihood of the current evidence with labelled places restricted to
            /// their labels (a full value pass; of the product of every observation, like
            /// `log_likelihood`; a label that a fused row reads as 0 counts with its exact
            /// fused value).
            pub fn labelled_log_likelihood(&mut self, labels: &Labels) -> Result<#t, #err> {
                #rt::check_labels(labels, NUM_CLASSES)?;
                self.0.labelled_log_likelihood::<H>(&MODEL, labels)
            }
        }
    }
}
