//! Every call into the generated API, and the storage it works on, lives here (and
//! only here): when the generated signatures change, this is the one module to adapt.
//!
//! Each compiled module (both maps, each with both model families: the GraphSPN and
//! the tree mixture have the same API) gets a zero-sized type implementing
//! [`Compiled`], whose entry points take no arguments and work on the module's buffers
//! (evidence, labels, marginals, MPE labels, the streaming `State`), so the firmware
//! can time them and measure their stack uniformly. The modules run one after the
//! other, so their buffers share one static arena in `.bss` ([`Compiled::start`]
//! resets it for the next module): the four sets would not fit the board's 128 KiB
//! of RAM side by side.

use core::mem::{ManuallyDrop, MaybeUninit};

use graphspn_firmware_maps::{
    demo_floor, demo_floor_trees, saarbrucken_seq2_night1, saarbrucken_seq2_night1_trees,
};
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
    /// Bytes of the module's buffers (its share of the arena).
    const BUFFER_BYTES: usize;
    /// Bytes of the module's streaming `State` (`STATE_BYTES`).
    const STATE_BYTES: usize;
    /// Resets the arena to this module's buffers (zeros, a new `State`); call before
    /// any other entry point of the module.
    fn start();
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
    /// `state.mpe(&mut mpe)`: the state's MPE labelling (a full max-product pass).
    fn state_mpe() -> CallResult;
    /// `state.labelled_log_likelihood(&labels)` (a full value pass).
    fn state_labelled_log_likelihood() -> CallResult;
}

/// Implements [`Compiled`] for module `$m` as type `$ty`, with its buffers (type
/// `$buf`) in the arena.
macro_rules! compiled {
    ($ty:ident, $buf:ident, $m:ident) => {
        /// The map
        #[doc = concat!("`", stringify!($m), "`")]
        /// with its buffers.
        pub struct $ty;

        /// The module's buffers.
        pub struct $buf {
            evidence: $m::Evidence,
            labels: $m::Labels,
            marginals: $m::Marginals,
            mpe: $m::Labels,
            state: $m::State,
            step_row: [f32; $m::NUM_CLASSES],
            step_place: usize,
            one: [f32; $m::NUM_CLASSES],
        }

        impl $buf {
            /// Fresh buffers: zeros and a new `State` (all zeros too).
            const NEW: $buf = $buf {
                evidence: [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES],
                labels: [0; $m::NUM_PLACES],
                marginals: [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES],
                mpe: [0; $m::NUM_PLACES],
                state: $m::State::new(),
                step_row: [0.0; $m::NUM_CLASSES],
                step_place: 0,
                one: [0.0; $m::NUM_CLASSES],
            };
        }

        impl $ty {
            /// The buffers in the arena. The firmware is single-threaded, runs one
            /// module at a time (after its `start`) and no caller keeps the reference
            /// beyond one call, so there is never a second live one.
            fn buffers() -> &'static mut $buf {
                // SAFETY: see above; the arena is a union of every module's buffers
                // (size and alignment fit), `start` wrote this module's buffers into it,
                // and interrupts (SysTick) never touch it.
                unsafe { &mut *(&raw mut ARENA).cast::<$buf>() }
            }
        }

        impl Compiled for $ty {
            const NAME: &'static str = stringify!($m);
            const PLACES: usize = $m::NUM_PLACES;
            const CLASSES: usize = $m::NUM_CLASSES;
            const UNKNOWN: u16 = $m::UNKNOWN;
            const BUFFER_BYTES: usize = core::mem::size_of::<$buf>();
            const STATE_BYTES: usize = $m::STATE_BYTES;
            fn start() {
                // SAFETY: as in `buffers`; writing a whole value needs no previous one.
                unsafe { (&raw mut ARENA).cast::<$buf>().write($buf::NEW) }
            }
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
            #[inline(never)]
            fn state_mpe() -> CallResult {
                let b = Self::buffers();
                b.state.mpe(&mut b.mpe)
            }
            #[inline(never)]
            fn state_labelled_log_likelihood() -> CallResult {
                let b = Self::buffers();
                b.state.labelled_log_likelihood(&b.labels)
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
mod floor_trees {
    use super::*;
    compiled!(DemoFloorTrees, Buffers, demo_floor_trees);
}
mod saarbrucken_trees {
    use super::*;
    compiled!(SaarbruckenTrees, Buffers, saarbrucken_seq2_night1_trees);
}
pub use floor::DemoFloor;
pub use floor_trees::DemoFloorTrees;
pub use saarbrucken::Saarbrucken;
pub use saarbrucken_trees::SaarbruckenTrees;

/// Room for the buffers of any one module (a union: the size and alignment of the
/// largest).
#[allow(dead_code)]
union Arena {
    floor: ManuallyDrop<floor::Buffers>,
    saarbrucken: ManuallyDrop<saarbrucken::Buffers>,
    floor_trees: ManuallyDrop<floor_trees::Buffers>,
    saarbrucken_trees: ManuallyDrop<saarbrucken_trees::Buffers>,
}

/// The buffers of the module being run (uninitialised until its `start`: `.bss`).
static mut ARENA: MaybeUninit<Arena> = MaybeUninit::uninit();
