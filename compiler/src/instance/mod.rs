//! The instance GraphSPN of a map (the paper's Alg. 1).
