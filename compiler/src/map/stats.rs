//! Map statistics.
