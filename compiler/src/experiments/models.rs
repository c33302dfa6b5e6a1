//! The models every experiment compares, their names, and how each one's marginals
//! are computed from a test graph's evidence.
//!
//! Results carry one value per model in [`Scores`], written to results.json as an
//! object keyed by model name (`{"Tree mixture": 0.97, "GraphSPN": …}`), so a script
//! can compare models without knowing the tool's internal order.

use std::fmt;
use std::marker::PhantomData;
use std::ops::{Index, IndexMut};

use serde::de::{MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::ReproduceError;
use super::settings::{GraphSpnSetting, MrfSetting};
use crate::instance::ComponentInstance;
use crate::map::TopoMap;
use crate::mrf::{BpResult, MrfModel};
use crate::treemix::TreeInstance;

/// Number of models compared.
pub const NUM_MODELS: usize = 7;

/// The models compared, in report order: ours (the tree mixture and GraphSPN) and
/// the MRFs, each with validated settings, then the paper-style models (GraphSPN
/// with the paper's settings; MRFs from raw joint frequencies with the raw
/// evidence).
pub const MODELS: [&str; NUM_MODELS] = [
    "Tree mixture",
    "GraphSPN",
    "MRF-2",
    "MRF-3",
    "GraphSPN paper",
    "MRF-2 paper",
    "MRF-3 paper",
];

/// Index into [`MODELS`] of the tree mixture.
pub const TREES: usize = 0;
/// Index into [`MODELS`] of the validated GraphSPN.
pub const GRAPHSPN: usize = 1;
/// Index into [`MODELS`] of the tuned MRF-2.
pub const MRF2: usize = 2;
/// Index into [`MODELS`] of the tuned MRF-3.
pub const MRF3: usize = 3;
/// Our models, each compared with the better tuned MRF of every cell.
pub const OUR_MODELS: [usize; 2] = [TREES, GRAPHSPN];
/// The tuned baselines.
pub const TUNED_MRFS: [usize; 2] = [MRF2, MRF3];
/// Indices into [`MODELS`] of every MRF (tuned and paper-style).
pub const MRF_MODELS: [usize; 4] = [2, 3, 5, 6];
/// Index into [`MODELS`] of the first paper-style model.
pub const FIRST_PAPER_MODEL: usize = 4;

/// One value per model of [`MODELS`] (by index), serialised as an object keyed by
/// model name in [`MODELS`] order; reading requires every model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores<T>(pub [T; NUM_MODELS]);

impl<T> Scores<T> {
    /// `f(k)` for every model index `k`.
    pub fn from_fn(f: impl FnMut(usize) -> T) -> Self {
        Scores(std::array::from_fn(f))
    }

    /// `(name, value)` of every model, in [`MODELS`] order.
    pub fn named(&self) -> impl Iterator<Item = (&'static str, &T)> {
        MODELS.iter().copied().zip(self.0.iter())
    }
}

impl<T> Index<usize> for Scores<T> {
    type Output = T;
    fn index(&self, k: usize) -> &T {
        &self.0[k]
    }
}

impl<T> IndexMut<usize> for Scores<T> {
    fn index_mut(&mut self, k: usize) -> &mut T {
        &mut self.0[k]
    }
}

/// Reads a `Scores<f64>` whose NaN entries (a figure over nothing) JSON holds as
/// `null` (serde_json writes NaN so).
pub(crate) fn scores_nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<Scores<f64>, D::Error> {
    let s = Scores::<Option<f64>>::deserialize(d)?;
    Ok(Scores(s.0.map(|v| v.unwrap_or(f64::NAN))))
}

impl<T: Serialize> Serialize for Scores<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(NUM_MODELS))?;
        for (name, v) in self.named() {
            m.serialize_entry(name, v)?;
        }
        m.end()
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Scores<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = Scores<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(
                    f,
                    "an object with one entry per model ({})",
                    MODELS.join(", ")
                )
            }
            fn visit_map<A: MapAccess<'de>>(self, mut a: A) -> Result<Scores<T>, A::Error> {
                let mut vals: [Option<T>; NUM_MODELS] = std::array::from_fn(|_| None);
                while let Some(name) = a.next_key::<String>()? {
                    let k = MODELS.iter().position(|m| *m == name).ok_or_else(|| {
                        serde::de::Error::custom(format!("unknown model {name:?}"))
                    })?;
                    vals[k] = Some(a.next_value()?);
                }
                if let Some(k) = vals.iter().position(Option::is_none) {
                    return Err(serde::de::Error::custom(format!(
                        "missing model {:?}",
                        MODELS[k]
                    )));
                }
                Ok(Scores(vals.map(|v| v.expect("checked above"))))
            }
        }
        d.deserialize_map(V(PhantomData))
    }
}

/// Each row raised to `exponent` and renormalised (`exponent = 1`: unchanged).
pub fn temper_rows(rows: &[Vec<f64>], exponent: f64) -> Vec<Vec<f64>> {
    if exponent == 1.0 {
        return rows.to_vec();
    }
    rows.iter()
        .map(|r| {
            let p: Vec<f64> = r.iter().map(|x| x.powf(exponent)).collect();
            let s: f64 = p.iter().sum();
            p.into_iter().map(|x| x / s).collect()
        })
        .collect()
}

/// The evidence rows GraphSPN is given: each row raised to `exponent`, multiplied
/// by `prior^-beta` (class-prior correction; `beta = 0`: none) and renormalised.
/// A place without evidence (a row of equal values) gets `prior^-beta`, so its
/// classes are no longer ranked by how common they were in training alone.
pub fn graphspn_rows(rows: &[Vec<f64>], exponent: f64, prior: &[f64], beta: f64) -> Vec<Vec<f64>> {
    let tempered = temper_rows(rows, exponent);
    if beta == 0.0 {
        return tempered;
    }
    let factor: Vec<f64> = prior.iter().map(|p| p.powf(-beta)).collect();
    tempered
        .into_iter()
        .map(|r| {
            let p: Vec<f64> = r.iter().zip(&factor).map(|(x, f)| x * f).collect();
            let s: f64 = p.iter().sum();
            p.into_iter().map(|x| x / s).collect()
        })
        .collect()
}

/// GraphSPN marginals of `map` (its instance `instance`, with no evidence set) given
/// evidence rows prepared by [`graphspn_rows`] with the setting's exponent and
/// prior correction (`prior`: the training maps' `class_prior`), mixed as the
/// setting says.
pub fn graphspn_marginals(
    instance: &ComponentInstance,
    map: &TopoMap,
    rows: &[Vec<f64>],
    setting: &GraphSpnSetting,
    prior: &[f64],
) -> Result<Vec<Vec<f64>>, ReproduceError> {
    let err = |source| ReproduceError::Inference {
        map: map.name.clone(),
        source,
    };
    let mut inst = instance.clone();
    inst.set_all_evidence(&graphspn_rows(
        rows,
        setting.evidence_exponent,
        prior,
        setting.prior_correction,
    ))
    .map_err(err)?;
    Ok(inst.marginals_mixed(setting.mixing).map_err(err)?.probs)
}

/// MRF marginals of `map` by loopy BP with the setting's evidence exponent and BP options.
pub fn mrf_marginals(
    model: &impl MrfModel,
    setting: &MrfSetting,
    map: &TopoMap,
    rows: &[Vec<f64>],
) -> Result<BpResult, ReproduceError> {
    model
        .infer(
            map,
            &temper_rows(rows, setting.evidence_exponent),
            &setting.bp,
        )
        .map_err(|source| ReproduceError::Mrf {
            what: map.name.clone(),
            source,
        })
}

/// Tree-mixture marginals of `map` (its instance, with no evidence set) given the raw
/// evidence rows: the model applies its own exponent and unary potential.
pub fn tree_marginals(
    instance: &TreeInstance,
    map: &TopoMap,
    rows: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>, ReproduceError> {
    let err = |source| ReproduceError::Trees {
        what: map.name.clone(),
        source,
    };
    let mut inst = instance.clone();
    inst.set_all_evidence(rows).map_err(err)?;
    Ok(inst.marginals().map_err(err)?.mixed.probs)
}
