//! Log-space arithmetic shared by the interpreter and generated code.
//!
//! (Filled in by the foundation issue: log-sum-exp with its error bound.)
