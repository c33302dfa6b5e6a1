//! A temperature on the template SPNs: every sum's weights raised to a power and
//! renormalised. For a template whose SPN is a full table (Pair, Three) this is
//! exactly the tempered distribution `p(y)^τ / Z`; for the Star's mixture it
//! tempers each mixing step. `τ < 1` flattens the learned co-occurrence
//! statistics (the counterpart of an MRF's coupling exponent), `τ = 1` leaves the
//! model unchanged.

use super::Model;
use crate::spn::{Node, Spn};

/// Largest template temperature. Far beyond it every sum's largest weight takes all
/// the mass (each sum becomes a maximum), which a temperature is not meant to do.
pub const MAX_TEMPERATURE: f64 = 10.0;

/// Why a temperature cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("template temperature {0}: {domain}", domain = self.domain())]
pub struct BadTemperature(pub f64);

impl BadTemperature {
    /// The domain, e.g. `must be finite and in (0, 10]`.
    pub fn domain(&self) -> String {
        format!("must be finite and in (0, {MAX_TEMPERATURE}]")
    }
}

/// Checks a temperature (finite, in (0, [`MAX_TEMPERATURE`]]).
pub fn check_temperature(tau: f64) -> Result<(), BadTemperature> {
    if tau.is_finite() && tau > 0.0 && tau <= MAX_TEMPERATURE {
        Ok(())
    } else {
        Err(BadTemperature(tau))
    }
}

/// Raises every sum weight of `spn` to the power `tau` and renormalises each sum
/// (weights summing to 1 again, to rounding). `tau = 1` changes nothing (not even
/// the last bit). Zero weights stay zero.
pub fn temper_spn(spn: &mut Spn, tau: f64) -> Result<(), BadTemperature> {
    check_temperature(tau)?;
    if tau == 1.0 {
        return Ok(());
    }
    for node in &mut spn.nodes {
        if let Node::Sum { weights, .. } = node {
            let mut powered: Vec<f64> = weights.iter().map(|w| w.powf(tau)).collect();
            let mut z: f64 = powered.iter().sum();
            if !(z > 0.0 && z.is_finite()) {
                // Every power under- or overflowed: the same ratios relative to the
                // largest weight (whose power is then 1), so the temperature is
                // applied, never skipped.
                let max = weights.iter().copied().fold(0.0, f64::max);
                if max > 0.0 {
                    powered = weights.iter().map(|w| (w / max).powf(tau)).collect();
                    z = powered.iter().sum();
                }
            }
            if z > 0.0 && z.is_finite() {
                for (w, p) in weights.iter_mut().zip(powered) {
                    *w = p / z;
                }
            }
        }
    }
    Ok(())
}

impl Model {
    /// This model with every template SPN tempered by `tau` (see [`temper_spn`]);
    /// the `temperature` entry of [`Model::settings`] records the product of the
    /// temperatures applied.
    pub fn tempered(&self, tau: f64) -> Result<Model, BadTemperature> {
        let mut out = self.clone();
        for spn in &mut out.spns {
            temper_spn(spn, tau)?;
        }
        if let serde_json::Value::Object(map) = &mut out.settings {
            let before = map
                .get("temperature")
                .and_then(serde_json::Value::as_f64)
                .unwrap_or(1.0);
            map.insert("temperature".into(), serde_json::json!(before * tau));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_sum(weights: Vec<f64>) -> Spn {
        Spn {
            classes: vec![2],
            nodes: vec![
                Node::Leaf { var: 0, class: 0 },
                Node::Leaf { var: 0, class: 1 },
                Node::Sum {
                    children: vec![0, 1],
                    weights,
                },
            ],
            root: 2,
        }
    }

    fn weights(spn: &Spn) -> Vec<f64> {
        match &spn.nodes[2] {
            Node::Sum { weights, .. } => weights.clone(),
            _ => unreachable!(),
        }
    }

    /// Weights are relative: when every power underflows (1e-40^10) the temperature is
    /// still applied, to the weights' ratios (it was skipped: recorded but not used).
    #[test]
    fn a_temperature_whose_powers_underflow_is_still_applied() {
        let mut spn = one_sum(vec![1e-40, 3e-40]);
        temper_spn(&mut spn, 10.0).unwrap();
        let w = weights(&spn);
        let expect = 3f64.powi(10);
        assert!((w[1] / w[0] - expect).abs() < 1e-6 * expect, "{w:?}");
        assert!((w[0] + w[1] - 1.0).abs() < 1e-12, "{w:?}");
        let mut spn = one_sum(vec![1e-40, 3e-40]);
        temper_spn(&mut spn, 2.0).unwrap();
        let w = weights(&spn);
        assert!(
            (w[0] - 0.1).abs() < 1e-12 && (w[1] - 0.9).abs() < 1e-12,
            "{w:?}"
        );
    }

    /// Weights whose powers neither under- nor overflow are tempered directly, `w^τ / Σ
    /// w^τ` bit for bit (the rescaling by the largest weight is for under- and overflow
    /// only); zero weights stay zero, and a sum of zeros stays zeros (not `0/0`).
    #[test]
    fn ordinary_weights_are_tempered_directly_and_zeros_stay_zero() {
        let mut x = 11u64;
        for _ in 0..50 {
            let ws: Vec<f64> = (0..3)
                .map(|_| {
                    x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                    (x >> 11) as f64 / (1u64 << 53) as f64 + 0.01
                })
                .collect();
            for tau in [0.3, 0.7, 2.5] {
                let mut spn = one_sum(ws.clone());
                temper_spn(&mut spn, tau).unwrap();
                let p: Vec<f64> = ws.iter().map(|w| w.powf(tau)).collect();
                let z: f64 = p.iter().sum();
                let want: Vec<f64> = p.iter().map(|v| v / z).collect();
                assert_eq!(weights(&spn), want, "{ws:?} at {tau}");
            }
        }
        let mut spn = one_sum(vec![0.0, 0.5]);
        temper_spn(&mut spn, 2.0).unwrap();
        assert_eq!(weights(&spn), vec![0.0, 1.0]);
        let mut spn = one_sum(vec![0.0, 0.0]);
        temper_spn(&mut spn, 2.0).unwrap();
        assert_eq!(
            weights(&spn),
            vec![0.0, 0.0],
            "a sum of zeros is left as it is"
        );
    }

    /// A temperature beyond the domain is refused, not recorded and skipped.
    #[test]
    fn a_temperature_out_of_its_domain_is_refused() {
        for bad in [0.0, -1.0, 10.5, 1e6, f64::INFINITY, f64::NAN] {
            let mut spn = one_sum(vec![0.25, 0.75]);
            let err = temper_spn(&mut spn, bad).unwrap_err();
            assert!(err.to_string().contains("(0, 10]"), "{err}");
            assert_eq!(weights(&spn), vec![0.25, 0.75]);
        }
        assert!(check_temperature(MAX_TEMPERATURE).is_ok());
    }
}
