//! Markov random field baselines (MRF-2, MRF-3) with loopy belief propagation.
