//! Queries on an instance: making one for a map, and marginals / likelihood / MPE
//! per place through the exact interpreter.

use thiserror::Error;

use super::{Instance, InstanceError, InstanceParams};
use crate::decompose::{DecomposeError, Decomposition, DecompositionParams, decompose_best};
use crate::interpreter::{Evaluator, Evidence, InferenceError, Marginals, Mpe};
use crate::learn::Model;
use crate::map::{ClassId, TopoMap};
use crate::spn::SpnError;

/// Why an instance could not be made or queried.
#[derive(Debug, Error)]
pub enum InstanceQueryError {
    /// Decomposing the map failed.
    #[error("decomposing map {map:?}: {source}")]
    Decompose {
        /// Map name.
        map: String,
        /// What failed.
        source: DecomposeError,
    },
    /// Assembling the instance failed.
    #[error(transparent)]
    Instance(#[from] InstanceError),
    /// The assembled SPN is invalid (a bug: the model's SPNs should be valid).
    #[error("the instance SPN is invalid: {0}")]
    InvalidSpn(#[from] SpnError),
    /// The interpreter rejected the query (bad or zero-probability evidence).
    #[error(transparent)]
    Inference(#[from] InferenceError),
    /// A template SPN of the model is invalid.
    #[error("the model's SPN for template {template:?} is invalid: {source}")]
    InvalidTemplateSpn {
        /// Template name.
        template: String,
        /// What is wrong.
        source: SpnError,
    },
    /// A place index outside the instance.
    #[error("place index {place} is out of range (the instance has {count} places)")]
    PlaceOutOfRange {
        /// The index given.
        place: usize,
        /// Number of places.
        count: usize,
    },
    /// A labelling has the wrong length or a class out of range.
    #[error("labelling: {0}")]
    BadLabels(String),
}

impl InstanceParams {
    /// The decompositions these settings choose for `map`: [`decompose_best`] over
    /// `model.templates`, `decompositions` kept of `candidates`, seeded by `seed`. What
    /// [`Instance::for_map`] and
    /// [`ComponentInstance::for_map`](super::ComponentInstance::for_map) mix.
    pub fn decompose(
        &self,
        model: &Model,
        map: &TopoMap,
    ) -> Result<Vec<Decomposition>, InstanceQueryError> {
        let dp = DecompositionParams {
            count: self.decompositions,
            candidates: self.candidates,
            seed: self.seed,
            strategy: self.strategy,
        };
        decompose_best(map, &model.templates, &dp).map_err(|source| InstanceQueryError::Decompose {
            map: map.name.clone(),
            source,
        })
    }
}

impl Instance {
    /// Decomposes `map` with [`decompose_best`] over `model.templates`
    /// (`params.decompositions` kept of `params.candidates`, seeded by `params.seed`)
    /// and assembles the instance (Alg. 1).
    pub fn for_map(
        model: &Model,
        map: &TopoMap,
        params: &InstanceParams,
    ) -> Result<Instance, InstanceQueryError> {
        let decompositions = params.decompose(model, map)?;
        Ok(Instance::build(model, map, decompositions)?)
    }
}

/// An [`Instance`] together with a compiled [`Evaluator`] of its SPN, answering
/// per-place queries. Evidence is one row of class likelihoods α per place (place
/// order); a uniform row means "no evidence". All results are exact (f64 log space).
#[derive(Clone, Debug)]
pub struct InstanceModel {
    /// The instance.
    pub instance: Instance,
    evaluator: Evaluator,
}

impl InstanceModel {
    /// Compiles the instance's SPN for querying (validates it, `O(E)`).
    pub fn new(instance: Instance) -> Result<Self, InstanceQueryError> {
        let evaluator = Evaluator::new(&instance.spn)?;
        Ok(InstanceModel {
            instance,
            evaluator,
        })
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.instance.num_places()
    }

    /// Uniform evidence (no observation at any place).
    pub fn uniform_evidence(&self) -> Evidence {
        Evidence::uniform(&self.instance.spn)
    }

    /// `P(Y_p = c | evidence)` for every place `p` and class `c`, and `ln P(evidence)`.
    pub fn marginals(&mut self, evidence: &Evidence) -> Result<Marginals, InstanceQueryError> {
        let free = vec![None; self.num_places()];
        Ok(self.evaluator.marginals(&free, evidence)?)
    }

    /// `ln P(Y_p = labels[p] for every labelled p, evidence)`: unlabelled places
    /// (`None`; an empty slice = none labelled) are summed out. With uniform evidence `1/C` per place this is the
    /// model's log-probability of the partial labelling plus `n·ln(1/C)` (the evidence
    /// rows multiply the leaves); pass rows of ones to get the pure model probability.
    pub fn log_likelihood_labelled(
        &mut self,
        labels: &[Option<ClassId>],
        evidence: &Evidence,
    ) -> Result<f64, InstanceQueryError> {
        let fixed = self.fixed(labels)?;
        Ok(self.evaluator.log_likelihood(&fixed, evidence)?)
    }

    /// Max-product (MPE) labelling of every place given the evidence, with places in
    /// `labels` clamped (an empty slice clamps none). The instance mixes decompositions, so it is not selective:
    /// the answer is the best (decomposition, labelling) pair's labelling; see
    /// [`Mpe`] for the bounds this gives.
    pub fn mpe(
        &mut self,
        labels: &[Option<ClassId>],
        evidence: &Evidence,
    ) -> Result<Mpe, InstanceQueryError> {
        let fixed = self.fixed(labels)?;
        Ok(self.evaluator.mpe(&fixed, evidence)?)
    }

    fn fixed(&self, labels: &[Option<ClassId>]) -> Result<Vec<Option<u32>>, InstanceQueryError> {
        let n = self.num_places();
        if labels.is_empty() {
            return Ok(vec![None; n]);
        }
        if labels.len() != n {
            return Err(InstanceQueryError::BadLabels(format!(
                "{} labels for {n} places",
                labels.len()
            )));
        }
        let c = self.instance.num_classes();
        if let Some(p) = labels
            .iter()
            .position(|l| l.is_some_and(|l| l as usize >= c))
        {
            return Err(InstanceQueryError::BadLabels(format!(
                "place index {p}: class {} out of range ({c} classes)",
                labels[p].unwrap_or_default()
            )));
        }
        Ok(labels.iter().map(|l| l.map(u32::from)).collect())
    }
}
