//! The instance GraphSPN of a map (the paper's Alg. 1).
//!
//! For a map and D decompositions of it into template-shaped components, the
//! instance SPN is a root sum with fixed uniform weights 1/D over D products; the
//! product of decomposition d multiplies one copy of the template SPN per
//! component of d, with the copy's leaves bound to the component's places.
//! Variable `p` of the instance SPN is place `p` of the map (place order), with
//! `model.classes.len()` classes.
//!
//! Every place has one leaf per class, shared by all copies. Copies of the same
//! component (same template on the same place tuple) occurring in several
//! decompositions are built once and shared, which keeps the DAG valid (scopes
//! are unchanged) and the instance smaller.

mod build;
mod export;

pub use build::{Instance, InstanceError, InstanceParams};
