//! The exact reference evaluator of an [`crate::spn::Spn`]: log-likelihood, marginals, MPE.
//!
//! Everything is computed in `f64` log space, so valid evidence never underflows to 0:
//! [`Evaluator`](crate::interpreter::Evaluator) flattens a validated SPN once into CSR arrays and answers any number
//! of queries in `O(E)` each. A query takes local [`Evidence`](crate::interpreter::Evidence) (class likelihoods α per
//! variable) and `fixed: &[Option<u32>]` (variables clamped to one class; `None` =
//! summed out). The free functions [`log_likelihood`](crate::interpreter::log_likelihood), [`marginals`](crate::interpreter::marginals) and [`mpe`](crate::interpreter::mpe) are
//! one-off conveniences.

mod eval;
mod evidence;

pub use eval::{BATCH, Evaluator, InferenceError, Marginals, Mpe, log_likelihood, marginals, mpe};
pub use evidence::{Evidence, check_row};
