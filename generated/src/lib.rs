//! Demo maps compiled by `graphspn` at build time: two modules per map, each a
//! straight-line, allocation-free evaluator of one model of the map — its instance
//! GraphSPN, and (`*_trees`) its tree mixture — with the same API (see
//! `demo/README.md` for where the maps and the models come from).
//!
//! - [`demo_floor`]: a synthetic 80-place office floor (`graphspn generate`), with the
//!   model trained on all COLD buildings (`graphspn train`); [`demo_floor_trees`] the
//!   tree mixture trained on them; [`demo_floor_truth`] holds its annotated classes.
//! - [`saarbrucken_seq2_night1`] and [`saarbrucken_seq2_night1_trees`]: the largest
//!   COLD map, 230 places (the benchmarks and `graphspn reproduce` use it).
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// The demo office floor (80 places, 10 classes, 5 decompositions, `f32`).
#[allow(missing_docs, clippy::all)]
pub mod demo_floor {
    include!(concat!(env!("OUT_DIR"), "/demo_floor.rs"));
}

/// The demo office floor's tree mixture (`demo/tree_model.json`, `f32`).
#[allow(missing_docs, clippy::all)]
pub mod demo_floor_trees {
    include!(concat!(env!("OUT_DIR"), "/demo_floor_trees.rs"));
}

/// Ground truth of [`demo_floor`].
pub mod demo_floor_truth {
    include!(concat!(env!("OUT_DIR"), "/demo_floor_truth.rs"));
}

/// Saarbrücken `seq2_night1`, the largest COLD map (230 places, `f32`).
#[allow(missing_docs, clippy::all)]
pub mod saarbrucken_seq2_night1 {
    include!(concat!(env!("OUT_DIR"), "/saarbrucken_seq2_night1.rs"));
}

/// Saarbrücken `seq2_night1`'s tree mixture (`demo/tree_model.json`, `f32`).
#[allow(missing_docs, clippy::all)]
pub mod saarbrucken_seq2_night1_trees {
    include!(concat!(
        env!("OUT_DIR"),
        "/saarbrucken_seq2_night1_trees.rs"
    ));
}

/// Ground truth of [`saarbrucken_seq2_night1`].
pub mod saarbrucken_seq2_night1_truth {
    include!(concat!(
        env!("OUT_DIR"),
        "/saarbrucken_seq2_night1_truth.rs"
    ));
}
