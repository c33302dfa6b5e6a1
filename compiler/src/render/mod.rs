//! SVG drawings of maps, per-place class distributions and decompositions.
