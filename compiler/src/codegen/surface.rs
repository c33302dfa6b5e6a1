//! The public surface every generated module has, whatever its model family: the
//! constants and array types, the validating wrappers of the stateless functions, the
//! `CompiledMap` impl, and the generator's report with its stack budget. The GraphSPN
//! emitter (`wiring/`) and the tree-mixture emitter (`trees/`) both build their
//! modules around these, so firmware and tests stay generic over both.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use super::emit::{Lit, array, int, rt};
use super::{CodegenError, CodegenOptions};

/// Bytes of one place's fused observations in a streaming state (the runtime's
/// `Fused`: per class a mantissa of `scalar` bytes and a `u16` deficit, then two `i32`
/// exponents, padded to the scalar's alignment).
pub(super) fn fused_bytes(classes: usize, scalar: usize) -> usize {
    let align = scalar.max(4);
    (classes * (scalar + 2) + 8).div_ceil(align) * align
}

/// What the generator knows about the generated code, beside its text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CodeReport {
    /// Components per call of kernel templates (GraphSPN; `1` on targets without float
    /// SIMD), or classes per lane vector of a row (tree mixture).
    pub lanes: usize,
    /// Distinct components of the map (GraphSPN: template copies; tree mixture: trees ×
    /// places, one message each).
    pub components: usize,
    /// Upper bound of the stack of `log_likelihood` (bytes), kernel frames included (for
    /// SIMD code an estimate: its frames depend on the target features).
    pub stack_log_likelihood: usize,
    /// Upper bound of the stack of `marginals` (bytes).
    pub stack_marginals: usize,
    /// Upper bound of the stack of `mpe` (bytes).
    pub stack_mpe: usize,
    /// Upper bound of the stack of any `State` call (bytes): an update plus query, and
    /// `State::mpe` / `State::labelled_log_likelihood`, which run the stateless passes
    /// on the fused evidence.
    pub stack_state: usize,
    /// Size of the streaming state (bytes): the tree mixture's exactly, the GraphSPN's
    /// up to the alignment padding of its fields (at most 16 bytes over).
    pub state_bytes: usize,
    /// Bytes of the `static` tables (GraphSPN: component places, decomposition sets,
    /// slots; tree mixture: the forests' orders, parents, children and roots, and the
    /// potentials).
    pub table_bytes: usize,
    /// Multiply(-add)s of one `log_likelihood` call (lane-vector operations).
    pub macs_log_likelihood: usize,
    /// Multiply(-add)s of one `marginals` call.
    pub macs_marginals: usize,
    /// Multiply(-add)s of one `mpe` call.
    pub macs_mpe: usize,
    /// Worst-case multiply(-add)s of one state update (`observe`) plus `marginals`.
    pub macs_observe_marginals: usize,
    /// Mean number of evaluation units one state update re-evaluates, over the places
    /// (GraphSPN: lane groups assembled from the components containing the place, one
    /// or more per template, single components in scalar code; tree mixture:
    /// places on the paths to the roots, summed over the trees).
    pub units_per_update: f64,
    /// Tree mixture on a target without an FPU with fixed-point messages: the relative
    /// error bound `η` of one message entry (the runtime's `message_error`); `None`
    /// where messages are `f32` (every other module).
    pub message_error: Option<f64>,
}

impl CodeReport {
    /// The bound of every `State` call from the bound of its updates and queries
    /// (`updates`): also `State::mpe` and `State::labelled_log_likelihood`, which run
    /// the stateless `mpe` and value passes (measured on Cortex-M4F: the 230-place
    /// tree mixture's `State::mpe` took 14,560 bytes where the updates' bound was
    /// 14,048).
    pub(super) fn state_bound(&self, updates: usize) -> usize {
        updates.max(self.stack_mpe).max(self.stack_log_likelihood)
    }

    /// The largest stack bound of any entry point.
    pub fn worst_stack(&self) -> usize {
        self.stack_marginals
            .max(self.stack_log_likelihood)
            .max(self.stack_mpe)
            .max(self.stack_state)
    }

    /// Fails when a stack bound exceeds the budget of `options`.
    pub(super) fn check_budget(&self, options: &CodegenOptions) -> Result<(), CodegenError> {
        let worst = self.worst_stack();
        if worst > options.stack_budget() {
            // Scalar code's figures are bounds; SIMD code's are estimates (its frames
            // depend on the target features it is built with).
            let needs = if self.lanes > 1 {
                "is estimated to need"
            } else {
                "needs up to"
            };
            return Err(CodegenError::BadOption(format!(
                "the generated code {needs} {worst} bytes of stack per call, more than the budget of {} bytes (raise it with `max_stack_bytes`, `--max-stack-bytes` of `graphspn compile`)",
                options.stack_budget()
            )));
        }
        Ok(())
    }
}

/// What the public constants of a module say: sizes, the report, ids and names.
pub(super) struct Surface<'a> {
    /// Scalar type and literals.
    pub l: &'a Lit,
    /// `"graphspn"` or `"tree_mixture"` (`MODEL_FAMILY`).
    pub family: &'static str,
    /// Places.
    pub n: usize,
    /// Classes.
    pub c: usize,
    /// Mixture components at the root: decompositions or trees.
    pub mixture: usize,
    /// Documentation of `NUM_DECOMPOSITIONS` (one line).
    pub mixture_doc: &'static str,
    /// `LANES`.
    pub lanes: usize,
    /// `NUM_COMPONENTS`.
    pub components: usize,
    /// The generator's report.
    pub report: &'a CodeReport,
    /// Place ids in place order.
    pub place_ids: Vec<u32>,
    /// Class names in class order.
    pub class_names: &'a [String],
    /// The evidence exponent `γ` (`EVIDENCE_EXPONENT`): rows enter the model as `α^γ`.
    pub evidence_exponent: u32,
}

/// The public constants (family, sizes, stack bounds, multiply-adds, ids, class names)
/// and the array types of the API.
pub(super) fn constants_and_types(s: &Surface) -> TokenStream {
    let t = s.l.ty();
    let r = s.report;
    let (family, mixture_doc) = (s.family, s.mixture_doc);
    let (n, c, d, lanes, components) = (
        int(s.n),
        int(s.c),
        int(s.mixture),
        int(s.lanes),
        int(s.components),
    );
    let (sl, sm, sp, ss) = (
        int(r.stack_log_likelihood),
        int(r.stack_marginals),
        int(r.stack_mpe),
        int(r.stack_state),
    );
    let (ml, mm, mp, mo) = (
        int(r.macs_log_likelihood),
        int(r.macs_marginals),
        int(r.macs_mpe),
        int(r.macs_observe_marginals),
    );
    let ids = array(
        s.place_ids
            .iter()
            .map(|&id| proc_macro2::Literal::u32_unsuffixed(id)),
    );
    let gamma = proc_macro2::Literal::u32_unsuffixed(s.evidence_exponent);
    // Scalar code's stack bounds hold (checked under QEMU on every microcontroller
    // target); SIMD code's frames depend on the target features it is built with
    // (a baseline x86-64 build spills more lane vectors than an AVX2 one).
    let stack = if s.lanes == 1 {
        "Upper bound of the stack (bytes)"
    } else {
        "Estimated stack (bytes; SIMD code: an estimate, not a bound, measured up to 36% above it on x86-64 without AVX2 and 2% with it)"
    };
    let [doc_sl, doc_sm, doc_sp, doc_ss] = [
        " of one `log_likelihood` or `labelled_log_likelihood` call.",
        " of one `marginals` call.",
        " of one `mpe` call.",
        " of any one [`State`] call.",
    ]
    .map(|what| String::from(" ") + stack + what);
    let names = array(
        s.class_names
            .iter()
            .map(|x| proc_macro2::Literal::string(x)),
    );
    quote! {
        /// The model family compiled into this module (`"graphspn"` or `"tree_mixture"`).
        pub const MODEL_FAMILY: &str = #family;
        /// Number of places of the map (the length of every evidence array).
        pub const NUM_PLACES: usize = #n;
        /// Number of classes per place.
        pub const NUM_CLASSES: usize = #c;
        #[doc = #mixture_doc]
        pub const NUM_DECOMPOSITIONS: usize = #d;
        /// SIMD lanes of the generated code (1 = scalar code): components per template call
        /// (GraphSPN), classes per lane vector (tree mixture).
        pub const LANES: usize = #lanes;
        /// Distinct components of the map: template copies (GraphSPN), trees × places
        /// (tree mixture: one cached message each).
        pub const NUM_COMPONENTS: usize = #components;
        #[doc = #doc_sl]
        pub const STACK_BYTES_LOG_LIKELIHOOD: usize = #sl;
        #[doc = #doc_sm]
        pub const STACK_BYTES_MARGINALS: usize = #sm;
        #[doc = #doc_sp]
        pub const STACK_BYTES_MPE: usize = #sp;
        #[doc = #doc_ss]
        pub const STACK_BYTES_STATE: usize = #ss;
        /// Bytes of one [`State`].
        pub const STATE_BYTES: usize = core::mem::size_of::<State>();
        /// Multiply(-add)s of one `log_likelihood` call, like every `MACS_*` in the code's
        /// own operations: lane vectors when `LANES > 1` (scalar and SIMD builds differ).
        pub const MACS_LOG_LIKELIHOOD: usize = #ml;
        /// Multiply(-add)s of one `marginals` call (lane vectors when `LANES > 1`).
        pub const MACS_MARGINALS: usize = #mm;
        /// Multiply(-add)s of one `mpe` call (lane vectors when `LANES > 1`).
        pub const MACS_MPE: usize = #mp;
        /// Worst-case multiply(-add)s of one [`State::observe`] plus [`State::marginals`].
        pub const MACS_OBSERVE_MARGINALS: usize = #mo;
        /// User-facing id of each place, in place order (evidence row `p` is place `PLACE_IDS[p]`).
        pub const PLACE_IDS: [u32; NUM_PLACES] = #ids;
        /// Class names in class-index order.
        pub const CLASS_NAMES: [&str; NUM_CLASSES] = #names;
        /// The evidence exponent `γ`: rows enter the model as `α^γ`, so scaling a row by `s`
        /// adds `γ · ln s` to every log value (1 for GraphSPN).
        pub const EVIDENCE_EXPONENT: u32 = #gamma;
        /// The label meaning "unknown" in label arrays.
        pub const UNKNOWN: u16 = u16::MAX;
        /// Local evidence: one row of non-negative likelihoods (one per class) per place.
        pub type Evidence = [[#t; NUM_CLASSES]; NUM_PLACES];
        /// Marginals: `P(Y_p = c | evidence)` per place and class.
        pub type Marginals = [[#t; NUM_CLASSES]; NUM_PLACES];
        /// One class index per place (`UNKNOWN` = not labelled).
        pub type Labels = [u16; NUM_PLACES];
    }
}

/// `pub fn <name>(<params>) -> Result<T, EvidenceError>`, documented by `docs` (one
/// string per line): validates the evidence `e` (and runs `more`), then calls
/// `<name>_unchecked(<args>)`.
pub(super) fn checked(
    l: &Lit,
    docs: &[&str],
    name: &str,
    params: TokenStream,
    args: TokenStream,
    more: TokenStream,
) -> TokenStream {
    let (t, check) = (l.ty(), l.helper("check"));
    let (f, unchecked) = (format_ident!("{name}"), format_ident!("{name}_unchecked"));
    quote! {
        #(#[doc = #docs])*
        pub fn #f(#params) -> Result<#t, ::graphspn_runtime::EvidenceError> {
            #check(e, &PLACE_IDS)?;
            #more
            #unchecked(#args)
        }
    }
}

/// The validating `labelled_log_likelihood` (evidence and labels checked), calling
/// `labelled_log_likelihood_unchecked`.
pub(super) fn checked_labelled(l: &Lit) -> TokenStream {
    let rt = rt();
    checked(
        l,
        &[
            " Natural log of the likelihood of the evidence with every labelled place restricted",
            " to its label (`UNKNOWN`: the whole row is used); labels `≥ NUM_CLASSES` are",
            " rejected as `LabelOutOfRange { place, label, classes: NUM_CLASSES }`.",
        ],
        "labelled_log_likelihood",
        quote!(labels: &Labels, e: &Evidence),
        quote!(labels, e),
        quote!(#rt::check_labels(labels, NUM_CLASSES)?;),
    )
}

/// `Map`, this map as a `graphspn_runtime::CompiledMap`.
pub(super) fn compiled_map_impl(l: &Lit) -> TokenStream {
    let (rt, t) = (rt(), l.ty());
    let err = quote!(::graphspn_runtime::EvidenceError);
    quote! {
        /// This map as a [`::graphspn_runtime::CompiledMap`], for code generic over compiled maps.
        pub struct Map;

        impl ::graphspn_runtime::CompiledMap for Map {
            type Scalar = #t;
            type Row = [#t; NUM_CLASSES];
            type State = State;
            const NUM_PLACES: usize = NUM_PLACES;
            const NUM_CLASSES: usize = NUM_CLASSES;
            const MODEL_FAMILY: &'static str = MODEL_FAMILY;
            const EVIDENCE_EXPONENT: u32 = EVIDENCE_EXPONENT;
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
            fn log_likelihood(e: &[Self::Row]) -> Result<#t, #err> {
                self::log_likelihood(#rt::fixed(e)?)
            }
            fn marginals(e: &[Self::Row], out: &mut [Self::Row]) -> Result<#t, #err> {
                self::marginals(#rt::fixed(e)?, #rt::fixed_mut(out)?)
            }
            fn mpe(e: &[Self::Row], labels: &mut [u16]) -> Result<#t, #err> {
                self::mpe(#rt::fixed(e)?, #rt::fixed_mut(labels)?)
            }
            fn labelled_log_likelihood(labels: &[u16], e: &[Self::Row]) -> Result<#t, #err> {
                self::labelled_log_likelihood(#rt::fixed(labels)?, #rt::fixed(e)?)
            }
            fn set_evidence(s: &mut State, place: usize, row: &Self::Row) -> Result<(), #err> {
                s.set_evidence(place, row)
            }
            fn observe(s: &mut State, place: usize, row: &Self::Row) -> Result<(), #err> {
                s.observe(place, row)
            }
            fn clear_evidence(s: &mut State, place: usize) -> Result<(), #err> {
                s.clear_evidence(place)
            }
            fn state_log_likelihood(s: &mut State) -> Result<#t, #err> {
                s.log_likelihood()
            }
            fn state_marginals(s: &mut State, out: &mut [Self::Row]) -> Result<#t, #err> {
                s.marginals(#rt::fixed_mut(out)?)
            }
            fn state_marginal(s: &mut State, place: usize, row: &mut Self::Row) -> Result<(), #err> {
                s.marginal(place, row)
            }
            fn state_evidence(s: &State) -> &[Self::Row] {
                s.evidence()
            }
            fn set_all(s: &mut State, e: &[Self::Row]) -> Result<(), #err> {
                s.set_all(#rt::fixed(e)?)
            }
            fn state_labelled_log_likelihood(s: &mut State, labels: &[u16]) -> Result<#t, #err> {
                s.labelled_log_likelihood(#rt::fixed(labels)?)
            }
            fn state_mpe(s: &mut State, labels: &mut [u16]) -> Result<#t, #err> {
                s.mpe(#rt::fixed_mut(labels)?)
            }
        }
    }
}
