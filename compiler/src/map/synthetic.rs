//! Synthetic generator.
