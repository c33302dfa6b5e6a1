//! Every call into the generated API, and the storage it works on, lives here (and
//! only here): when the generated signatures change, this is the one module to adapt.
//!
//! Each map gets a zero-sized type implementing [`Compiled`], whose entry points take
//! no arguments and work on the map's buffers in `.bss` (evidence, labels,
//! marginals, MPE labels, the streaming `State`), so the firmware can time them and
//! measure their stack uniformly.

use graphspn_firmware_maps::{demo_floor, saarbrucken_seq2_night1};
use graphspn_runtime::EvidenceError;

/// Result of one generated call: the `f32` it returns (a log-likelihood or
/// MPE value, natural log) or the evidence error.
pub type CallResult = Result<f32, EvidenceError>;

/// Views of a map's buffers: evidence rows and marginals (flattened, `classes`
/// values per place), the labels given to `labelled_log_likelihood`, and the
/// labels `mpe` writes.
pub struct Views<'a> {
    /// Evidence, `NUM_PLACES × NUM_CLASSES` likelihoods.
    pub evidence: &'a mut [f32],
    /// Labels for `labelled_log_likelihood` (`UNKNOWN` = unlabelled).
    pub labels: &'a mut [u16],
    /// Marginals written by `marginals`, `NUM_PLACES × NUM_CLASSES`.
    pub marginals: &'a mut [f32],
    /// Labelling written by `mpe`.
    pub mpe: &'a mut [u16],
    /// The observation the next streaming step fuses in (`NUM_CLASSES` values).
    pub step_row: &'a mut [f32],
    /// The place of the next streaming step.
    pub step_place: &'a mut usize,
}

/// One compiled map as the firmware uses it.
pub trait Compiled {
    /// Module name.
    const NAME: &'static str;
    /// Places of the map.
    const PLACES: usize;
    /// Classes per place.
    const CLASSES: usize;
    /// The "unknown" label.
    const UNKNOWN: u16;
    /// Runs `f` on the map's buffers. Not re-entrant: never call it, or an entry
    /// point, from inside `f`.
    fn with_views<R>(f: impl FnOnce(Views<'_>) -> R) -> R;
    /// `log_likelihood(evidence)`.
    fn log_likelihood() -> CallResult;
    /// `marginals(evidence, &mut marginals)`.
    fn marginals() -> CallResult;
    /// `mpe(evidence, &mut mpe)`.
    fn mpe() -> CallResult;
    /// `labelled_log_likelihood(&labels, evidence)`.
    fn labelled_log_likelihood() -> CallResult;
    /// `state.set_all(evidence)` and `state.log_likelihood()`: fills the streaming
    /// state (every component evaluated once).
    fn state_set_all() -> CallResult;
    /// One streaming step: `state.observe(step_place, &step_row)` and
    /// `state.marginals(&mut marginals)` (returns the log-likelihood).
    fn observe_marginals() -> CallResult;
    /// One streaming step for one place: `state.observe(step_place, &step_row)` and
    /// `state.marginal(step_place, ..)` (returns the place's marginal of class 0).
    fn observe_marginal() -> CallResult;
    /// `state.marginals(&mut marginals)` without a new observation.
    fn state_marginals() -> CallResult;
}

/// Implements [`Compiled`] for module `$m` as type `$ty`, with its buffers in a
/// `static mut` of type `$buf`.
macro_rules! compiled {
    ($ty:ident, $buf:ident, $m:ident) => {
        /// The map
        #[doc = concat!("`", stringify!($m), "`")]
        /// with its buffers.
        pub struct $ty;

        struct $buf {
            evidence: $m::Evidence,
            labels: $m::Labels,
            marginals: $m::Marginals,
            mpe: $m::Labels,
            state: $m::State,
            step_row: [f32; $m::NUM_CLASSES],
            step_place: usize,
            one: [f32; $m::NUM_CLASSES],
        }

        static mut BUFFERS_OF_MAP: $buf = $buf {
            evidence: [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES],
            labels: [0; $m::NUM_PLACES],
            marginals: [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES],
            mpe: [0; $m::NUM_PLACES],
            state: $m::State::new(),
            step_row: [0.0; $m::NUM_CLASSES],
            step_place: 0,
            one: [0.0; $m::NUM_CLASSES],
        };

        impl $ty {
            /// The buffers. The firmware is single-threaded and no caller keeps the
            /// reference beyond one call, so there is never a second live one.
            fn buffers() -> &'static mut $buf {
                // SAFETY: see above; interrupts (SysTick) never touch the buffers.
                unsafe { &mut *(&raw mut BUFFERS_OF_MAP) }
            }
        }

        impl Compiled for $ty {
            const NAME: &'static str = stringify!($m);
            const PLACES: usize = $m::NUM_PLACES;
            const CLASSES: usize = $m::NUM_CLASSES;
            const UNKNOWN: u16 = $m::UNKNOWN;
            fn with_views<R>(f: impl FnOnce(Views<'_>) -> R) -> R {
                let b = Self::buffers();
                f(Views {
                    evidence: b.evidence.as_flattened_mut(),
                    labels: &mut b.labels,
                    marginals: b.marginals.as_flattened_mut(),
                    mpe: &mut b.mpe,
                    step_row: &mut b.step_row,
                    step_place: &mut b.step_place,
                })
            }
            #[inline(never)]
            fn log_likelihood() -> CallResult {
                let b = Self::buffers();
                $m::log_likelihood(&b.evidence)
            }
            #[inline(never)]
            fn marginals() -> CallResult {
                let b = Self::buffers();
                $m::marginals(&b.evidence, &mut b.marginals)
            }
            #[inline(never)]
            fn mpe() -> CallResult {
                let b = Self::buffers();
                $m::mpe(&b.evidence, &mut b.mpe)
            }
            #[inline(never)]
            fn labelled_log_likelihood() -> CallResult {
                let b = Self::buffers();
                $m::labelled_log_likelihood(&b.labels, &b.evidence)
            }
            #[inline(never)]
            fn state_set_all() -> CallResult {
                let b = Self::buffers();
                b.state.set_all(&b.evidence)?;
                b.state.log_likelihood()
            }
            #[inline(never)]
            fn observe_marginals() -> CallResult {
                let b = Self::buffers();
                b.state.observe(b.step_place, &b.step_row)?;
                b.state.marginals(&mut b.marginals)
            }
            #[inline(never)]
            fn observe_marginal() -> CallResult {
                let b = Self::buffers();
                b.state.observe(b.step_place, &b.step_row)?;
                b.state.marginal(b.step_place, &mut b.one)?;
                Ok(b.one[0])
            }
            fn state_marginals() -> CallResult {
                let b = Self::buffers();
                b.state.marginals(&mut b.marginals)
            }
        }
    };
}

mod floor {
    use super::*;
    compiled!(DemoFloor, Buffers, demo_floor);
}
mod saarbrucken {
    use super::*;
    compiled!(Saarbrucken, Buffers, saarbrucken_seq2_night1);
}
pub use floor::DemoFloor;
pub use saarbrucken::Saarbrucken;
