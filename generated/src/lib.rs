//! Demo maps compiled by `graphspn` at build time: one module per map, each a
//! straight-line, allocation-free evaluator of its instance GraphSPN.
#![no_std]
#![forbid(unsafe_code)]
