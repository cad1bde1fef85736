//! The discrete Bayes filter over locations of RTAB-Map's loop-closure detection (Angeli,
//! Filliat, Doncieux and Meyer, "Fast and incremental method for loop-closure detection
//! using bags of visual words", IEEE T-RO 2008; Labbé and Michaud, "Appearance-based loop
//! closure detection for online large-scale and long-term operation", IEEE T-RO 2013, §III).
//!
//! The state is "the new image closes a loop with location i" for every location in
//! working memory, plus the virtual place ("it is a new place"). Between images the belief
//! spreads along the time order of the locations (a location's neighbours 1, 2, … apart)
//! with the `Bayes/PredictionLC` coefficients, and then each state is weighed by its
//! likelihood: `p(S_t | L^t) = η p(L_t | S_t) Σ_i p(S_t | S_{t−1} = i) p(S_{t−1} = i | L^{t−1})`.

use std::collections::BTreeMap;

/// Location id.
pub type Id = u64;

#[derive(Debug, Clone)]
pub struct BayesFilter {
    /// `[to virtual, to itself, to a neighbour 1 apart, 2 apart, …]` from a location.
    prediction: Vec<f64>,
    /// Probability that the virtual place stays the virtual place.
    virtual_prior: f64,
    posterior: BTreeMap<Id, f64>,
    virtual_posterior: f64,
}

/// The posterior after an update.
#[derive(Debug, Clone, PartialEq)]
pub struct Posterior {
    pub virtual_place: f64,
    pub locations: BTreeMap<Id, f64>,
}

impl Posterior {
    /// The most probable location and its probability.
    pub fn best(&self) -> Option<(Id, f64)> {
        self.locations
            .iter()
            .fold(None, |best: Option<(Id, f64)>, (&id, &p)| match best {
                Some((_, q)) if q >= p => best,
                _ => Some((id, p)),
            })
    }
}

impl BayesFilter {
    pub fn new(prediction: Vec<f64>, virtual_prior: f64) -> Self {
        Self {
            prediction,
            virtual_prior,
            posterior: BTreeMap::new(),
            virtual_posterior: 1.0,
        }
    }

    /// Forgets a location (it left working memory).
    pub fn remove(&mut self, id: Id) {
        self.posterior.remove(&id);
    }

    /// One step: `candidates` are the working-memory locations in time order with their
    /// likelihoods; `virtual_likelihood` is the new place's.
    pub fn update(&mut self, candidates: &[(Id, f64)], virtual_likelihood: f64) -> Posterior {
        let n = candidates.len();
        let index: BTreeMap<Id, usize> = candidates
            .iter()
            .enumerate()
            .map(|(k, (id, _))| (*id, k))
            .collect();
        // Prediction: the prior of every state from last step's posterior.
        let mut prior = vec![0.0; n];
        let mut prior_virtual = self.virtual_posterior * self.virtual_prior;
        if n > 0 {
            let spread = self.virtual_posterior * (1.0 - self.virtual_prior) / n as f64;
            prior.iter_mut().for_each(|p| *p += spread);
        } else {
            prior_virtual = self.virtual_posterior;
        }
        let to_virtual = self.prediction[0];
        let kernel = &self.prediction[1..];
        for (&id, &p) in &self.posterior {
            let Some(&j) = index.get(&id) else { continue };
            if p == 0.0 {
                continue;
            }
            prior_virtual += p * to_virtual;
            // The neighbours that exist, normalised to what is left after the virtual place.
            let reach = kernel.len() - 1;
            let lo = j.saturating_sub(reach);
            let hi = (j + reach).min(n - 1);
            let total: f64 = (lo..=hi).map(|i| kernel[i.abs_diff(j)]).sum();
            for (i, slot) in prior.iter_mut().enumerate().take(hi + 1).skip(lo) {
                *slot += p * (1.0 - to_virtual) * kernel[i.abs_diff(j)] / total;
            }
        }
        // Update with the likelihoods and normalise.
        let mut posterior: Vec<f64> = prior
            .iter()
            .zip(candidates)
            .map(|(p, (_, l))| p * l)
            .collect();
        let mut virtual_place = prior_virtual * virtual_likelihood;
        let sum: f64 = posterior.iter().sum::<f64>() + virtual_place;
        if sum > 0.0 && sum.is_finite() {
            posterior.iter_mut().for_each(|p| *p /= sum);
            virtual_place /= sum;
        } else {
            posterior.iter_mut().for_each(|p| *p = 0.0);
            virtual_place = 1.0;
        }
        self.posterior = candidates
            .iter()
            .map(|(id, _)| *id)
            .zip(posterior.iter().copied())
            .collect();
        self.virtual_posterior = virtual_place;
        Posterior {
            virtual_place,
            locations: self.posterior.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filter() -> BayesFilter {
        BayesFilter::new(vec![0.1, 0.36, 0.30, 0.16, 0.062, 0.0151], 0.9)
    }

    #[test]
    fn flat_likelihood_keeps_the_new_place() {
        let mut f = filter();
        let candidates: Vec<(Id, f64)> = (0..20).map(|i| (i, 1.0)).collect();
        let p = f.update(&candidates, 1.0);
        assert!((p.virtual_place - 0.9).abs() < 1e-12, "{}", p.virtual_place);
        let sum: f64 = p.locations.values().sum::<f64>() + p.virtual_place;
        assert!((sum - 1.0).abs() < 1e-12);
    }

    #[test]
    fn repeated_evidence_builds_a_hypothesis_and_spreads_to_neighbours() {
        let mut f = filter();
        let mut candidates: Vec<(Id, f64)> = (0..30).map(|i| (i, 1.0)).collect();
        candidates[12].1 = 4.0;
        let first = f.update(&candidates, 1.0);
        let (best, p1) = first.best().expect("a best location");
        assert_eq!(best, 12);
        // Next image: the robot moved on, so the evidence moves to location 13.
        candidates[12].1 = 1.0;
        candidates[13].1 = 4.0;
        let second = f.update(&candidates, 1.0);
        let (best, p2) = second.best().expect("a best location");
        assert_eq!(best, 13);
        assert!(
            p2 > p1,
            "belief should grow with consistent evidence: {p1} then {p2}"
        );
        // By hand for the first step: prior 0.1/30 each, posterior ∝ 4 × prior for 12.
        let prior = 0.1 / 30.0;
        let expected = 4.0 * prior / (0.9 + 29.0 * prior + 4.0 * prior);
        assert!((p1 - expected).abs() < 1e-12, "{p1} vs {expected}");
    }
}
