//! The trait every compiled map implements, so firmware can be generic over maps.

use crate::EvidenceError;

/// A model of one known map compiled by `graphspn-compiler`: a GraphSPN instance
/// (template SPNs mixed over decompositions of the map) or a tree mixture (exact
/// spanning-forest models mixed at the root); both offer the same API.
///
/// Evidence is one row per place (place order, see [`CompiledMap::PLACE_IDS`]),
/// each row holding one non-negative likelihood per class. Rows are the
/// associated type [`CompiledMap::Row`] (`[Scalar; NUM_CLASSES]`), passed as slices
/// so code generic over maps needs no const-generic arithmetic; a slice whose length
/// is not [`CompiledMap::NUM_PLACES`] (evidence, marginals or labels) is rejected with
/// [`EvidenceError::WrongLength`]. Labels are class indices, `u16::MAX` = unknown.
///
/// All methods are allocation-free and never panic.
pub trait CompiledMap {
    /// The floating-point type of evidence and results (`f32` or `f64`).
    type Scalar: Copy + PartialOrd + Default + core::fmt::Debug + 'static;
    /// One row of evidence or marginals: `[Self::Scalar; NUM_CLASSES]`.
    type Row: Copy + AsRef<[Self::Scalar]> + AsMut<[Self::Scalar]> + 'static;
    /// The model family (`"graphspn"` or `"tree_mixture"`).
    const MODEL_FAMILY: &'static str;
    /// The evidence exponent `γ`: rows enter the model as `α^γ`, so scaling a row by `s`
    /// adds `γ · ln s` to every log value (1 for GraphSPN).
    const EVIDENCE_EXPONENT: u32;
    /// Number of places of the map.
    const NUM_PLACES: usize;
    /// Number of classes per place.
    const NUM_CLASSES: usize;
    /// Number of mixture components at the root (uniform weights): decompositions of
    /// the map (GraphSPN) or spanning trees (tree mixture).
    const NUM_DECOMPOSITIONS: usize;
    /// User-facing id of each place, in place order.
    const PLACE_IDS: &'static [u32];
    /// Class names, in class-index order.
    const CLASS_NAMES: &'static [&'static str];
    /// A row of zeros, to initialise evidence and marginal buffers in generic code.
    const ZERO_ROW: Self::Row;
    /// SIMD lanes of the generated code (1 = scalar code): components per template call
    /// (GraphSPN) or classes per lane vector (tree mixture).
    const LANES: usize;
    /// Distinct components of the map: template copies (GraphSPN), trees × places (tree
    /// mixture).
    const NUM_COMPONENTS: usize;
    /// Upper bound of the stack (bytes) of `log_likelihood` / `labelled_log_likelihood`
    /// (each `STACK_BYTES_*` is a bound for scalar code, `LANES == 1`, and an estimate
    /// for SIMD code, whose frames depend on the target features it is built with).
    const STACK_BYTES_LOG_LIKELIHOOD: usize;
    /// Upper bound of the stack (bytes) of `marginals`.
    const STACK_BYTES_MARGINALS: usize;
    /// Upper bound of the stack (bytes) of `mpe`.
    const STACK_BYTES_MPE: usize;
    /// Upper bound of the stack (bytes) of any state call (updates, queries, and the
    /// state's `mpe` and `labelled_log_likelihood`, which run the stateless passes).
    const STACK_BYTES_STATE: usize;
    /// Bytes of one [`CompiledMap::State`].
    const STATE_BYTES: usize;
    /// Multiply(-add)s of one `log_likelihood` call. Every `MACS_*` counts the code's
    /// own operations: lane-vector operations when `LANES > 1` (each the work of up to
    /// `LANES` scalar ones), so a scalar and a SIMD build of one map give different
    /// figures.
    const MACS_LOG_LIKELIHOOD: usize;
    /// Multiply(-add)s of one `marginals` call (lane-vector operations when `LANES > 1`).
    const MACS_MARGINALS: usize;
    /// Multiply(-add)s of one `mpe` call (lane-vector operations when `LANES > 1`).
    const MACS_MPE: usize;
    /// Worst-case multiply(-add)s of one state update plus state marginals (lane-vector
    /// operations when `LANES > 1`).
    const MACS_OBSERVE_MARGINALS: usize;
    /// The streaming state of this map (see the generated `State`).
    type State;
    /// A state without evidence (usable in a `static`).
    const NEW_STATE: Self::State;

    /// Natural log of the likelihood of the evidence, `ln S(α)`.
    fn log_likelihood(e: &[Self::Row]) -> Result<Self::Scalar, EvidenceError>;

    /// Writes `P(Y_p = c | α)` for every place into `out` and returns `ln S(α)`.
    fn marginals(e: &[Self::Row], out: &mut [Self::Row]) -> Result<Self::Scalar, EvidenceError>;

    /// Writes the max-product (MPE) labelling into `labels` and returns its
    /// natural-log max-product value.
    fn mpe(e: &[Self::Row], labels: &mut [u16]) -> Result<Self::Scalar, EvidenceError>;

    /// Natural log of the likelihood of the evidence with every labelled place
    /// restricted to its label (`u16::MAX` = unknown: the full row is used).
    fn labelled_log_likelihood(
        labels: &[u16],
        e: &[Self::Row],
    ) -> Result<Self::Scalar, EvidenceError>;

    /// Streaming: sets the evidence row of place index `place` and updates the cache
    /// (only the components containing the place, or its paths to the roots, are
    /// re-evaluated).
    fn set_evidence(
        s: &mut Self::State,
        place: usize,
        row: &Self::Row,
    ) -> Result<(), EvidenceError>;

    /// Streaming: fuses an observation into the place's row (element-wise product,
    /// kept per class as a mantissa and a binary exponent: one rounding per observation
    /// and class, no underflow; the row inference reads is that product scaled by a
    /// power of two) and updates the cache.
    fn observe(s: &mut Self::State, place: usize, row: &Self::Row) -> Result<(), EvidenceError>;

    /// Streaming: removes the evidence of a place (row of ones) and updates the cache.
    fn clear_evidence(s: &mut Self::State, place: usize) -> Result<(), EvidenceError>;

    /// Streaming: `ln S` of the state's evidence, from the cache.
    fn state_log_likelihood(s: &mut Self::State) -> Result<Self::Scalar, EvidenceError>;

    /// Streaming: the marginals of every place, from the cache; returns `ln S`.
    fn state_marginals(
        s: &mut Self::State,
        out: &mut [Self::Row],
    ) -> Result<Self::Scalar, EvidenceError>;

    /// Streaming: the marginal of one place, from the cache (GraphSPN: `O(D·C)`; tree
    /// mixture: `O(T·height·C²)`, a walk from each root to the place).
    fn state_marginal(
        s: &mut Self::State,
        place: usize,
        row: &mut Self::Row,
    ) -> Result<(), EvidenceError>;

    /// Streaming: the state's evidence rows (all ones where a place has none).
    fn state_evidence(s: &Self::State) -> &[Self::Row];

    /// Streaming: replaces all evidence and re-evaluates every component.
    fn set_all(s: &mut Self::State, e: &[Self::Row]) -> Result<(), EvidenceError>;

    /// Streaming: the labelled log-likelihood of the state's evidence (a full pass).
    fn state_labelled_log_likelihood(
        s: &mut Self::State,
        labels: &[u16],
    ) -> Result<Self::Scalar, EvidenceError>;

    /// Streaming: the MPE labelling of the state's evidence (a full max-product pass).
    fn state_mpe(s: &mut Self::State, labels: &mut [u16]) -> Result<Self::Scalar, EvidenceError>;
}

/// Converts a slice of one entry per place into a fixed-size array reference, or
/// reports [`EvidenceError::WrongLength`].
pub fn fixed<T, const N: usize>(s: &[T]) -> Result<&[T; N], EvidenceError> {
    s.try_into().map_err(|_| EvidenceError::WrongLength {
        expected: N,
        found: s.len(),
    })
}

/// Mutable version of [`fixed`].
pub fn fixed_mut<T, const N: usize>(s: &mut [T]) -> Result<&mut [T; N], EvidenceError> {
    let found = s.len();
    s.try_into()
        .map_err(|_| EvidenceError::WrongLength { expected: N, found })
}
