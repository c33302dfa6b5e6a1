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

//!
//! - [`Instance::build`](crate::instance::Instance::build) / [`Instance::for_map`](crate::instance::Instance::for_map): assembly from given decompositions or
//!   from [`crate::decompose::decompose_best`];
//! - [`InstanceModel`](crate::instance::InstanceModel): marginals, log-likelihood of a partial labelling and MPE per
//!   place through the exact interpreter;
//! - [`Instance::update`](crate::instance::Instance::update) / [`Instance::grow`](crate::instance::Instance::grow) / [`grow_decompositions`](crate::instance::grow_decompositions): incremental
//!   updates when the map grows, keeping untouched template copies;
//! - [`ComponentInstance`](crate::instance::ComponentInstance): the same queries evaluated component by component against
//!   the shared template networks (memory linear in places, no explicit SPN), with
//!   incremental evidence updates and growth;
//! - [`Instance::to_json`](crate::instance::Instance::to_json) / [`Instance::to_dot`](crate::instance::Instance::to_dot): export.

mod build;
mod components;
mod export;
mod grow;
mod query;

pub use crate::spn::Mixing;
pub use build::{CopyStats, Instance, InstanceError, InstanceParams};
pub use components::{ComponentInstance, estimated_component_bytes, estimated_explicit_bytes};
pub use export::{spn_dot, tree_instance_json};
pub use grow::grow_decompositions;
pub use query::{InstanceModel, InstanceQueryError};
