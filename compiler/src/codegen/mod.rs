//! Code generation: straight-line `no_std` Rust for a known map, and the `build.rs` builder.
