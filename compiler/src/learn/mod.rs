//! Template SPN structure generation, EM training and the model file.

pub mod model;

pub use model::Model;
