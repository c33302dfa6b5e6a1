//! The exact reference evaluator of an [`crate::spn::Spn`]: log-likelihood, marginals, MPE.
