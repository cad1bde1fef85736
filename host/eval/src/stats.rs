//! Statistics of an error series, as evo reports them: rmse, mean, median, std
//! (population, i.e. divided by n), min, max and sse (sum of squared errors).

use serde::{Deserialize, Serialize};

use crate::EvalError;

/// Statistics of a series of errors; fields in the order of `vinebench eval --json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Statistics {
    /// Number of errors (pose pairs).
    pub pairs: usize,
    /// `sqrt(sse / n)`.
    pub rmse: f64,
    /// Arithmetic mean.
    pub mean: f64,
    /// Middle value; mean of the two middle values for even `n`.
    pub median: f64,
    /// Population standard deviation `sqrt(Σ (e - mean)² / n)`.
    pub std: f64,
    /// Smallest error.
    pub min: f64,
    /// Largest error.
    pub max: f64,
    /// Sum of squared errors.
    pub sse: f64,
}

impl Statistics {
    /// The statistics of `errors`; errors if the series is empty.
    pub fn from_errors(errors: &[f64]) -> Result<Self, EvalError> {
        let n = errors.len();
        if n == 0 {
            return Err(EvalError::TooFewPoses {
                what: "statistics",
                needed: 1,
                got: 0,
            });
        }
        let count = n as f64;
        let sum: f64 = errors.iter().sum();
        let sse: f64 = errors.iter().map(|e| e * e).sum();
        let mean = sum / count;
        let variance = errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / count;
        let (min, max) = errors
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
                (lo.min(e), hi.max(e))
            });
        let mut sorted = errors.to_vec();
        let mid = n / 2;
        let (below, &mut upper, _) = sorted.select_nth_unstable_by(mid, f64::total_cmp);
        let median = if n % 2 == 1 {
            upper
        } else {
            let lower = below.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (lower + upper) / 2.0
        };
        Ok(Self {
            pairs: n,
            rmse: (sse / count).sqrt(),
            mean,
            median,
            std: variance.sqrt(),
            min,
            max,
            sse,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_of_hand_computed_series() {
        // errors 1, 2, 3, 4: sse 30, rmse sqrt(7.5), mean 2.5, median 2.5,
        // population variance (2.25 + 0.25 + 0.25 + 2.25) / 4 = 1.25.
        let s = Statistics::from_errors(&[4.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(s.pairs, 4, "expected 4 pairs");
        assert_eq!(s.sse, 30.0, "expected sse 30");
        assert!(
            (s.rmse - 7.5f64.sqrt()).abs() < 1e-15,
            "expected rmse sqrt(7.5), got {}",
            s.rmse
        );
        assert_eq!(
            (s.mean, s.median),
            (2.5, 2.5),
            "expected mean and median 2.5"
        );
        assert!(
            (s.std - 1.25f64.sqrt()).abs() < 1e-15,
            "expected population std sqrt(1.25), got {}",
            s.std
        );
        assert_eq!((s.min, s.max), (1.0, 4.0), "expected min 1 and max 4");
        let odd = Statistics::from_errors(&[5.0, 1.0, 3.0]).unwrap();
        assert_eq!(odd.median, 3.0, "expected the middle value 3 for odd n");
    }

    #[test]
    fn empty_series_is_an_error() {
        assert!(
            Statistics::from_errors(&[]).is_err(),
            "expected an error for no errors"
        );
    }
}
