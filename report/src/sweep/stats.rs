//! Statistics of a stream of numbers in constant memory, with the 95 % confidence interval of
//! the mean a paper reports.

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, StudentsT};

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    /// The values counted (a metric a run has no value of is left out: the arrival of a fleet
    /// that never arrived, the re-synchronisation of a run without a fault).
    pub n: u64,
    pub mean: f64,
    /// The sample's standard deviation (over n − 1); `None` (null) for one value, which has no
    /// spread to measure.
    pub std: Option<f64>,
    /// Half the width of the 95 % confidence interval of the mean, Student's t with n − 1
    /// degrees of freedom: the mean is `mean ± ci95`. `None` with one value.
    pub ci95: Option<f64>,
    pub min: f64,
    pub max: f64,
}

/// Mean, standard deviation and range by Welford's update, so that a sweep of a million runs
/// holds one accumulator per grid point and metric, not its rows.
#[derive(Debug, Clone, Copy, Default)]
pub struct Running {
    n: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
}

impl Running {
    /// Counts `x` if it is a finite number.
    pub fn push(&mut self, x: Option<f64>) {
        let Some(x) = x.filter(|x| x.is_finite()) else { return };
        if self.n == 0 {
            (self.min, self.max) = (x, x);
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }

    pub fn stats(&self) -> Option<Stats> {
        (self.n > 0).then(|| {
            let std = (self.n > 1).then(|| (self.m2 / (self.n - 1) as f64).sqrt());
            Stats {
                n: self.n,
                mean: self.mean,
                std,
                ci95: std.map(|s| t_975(self.n - 1) * s / (self.n as f64).sqrt()),
                min: self.min,
                max: self.max,
            }
        })
    }
}

/// The 0.975 quantile of Student's t with `df` ≥ 1 degrees of freedom.
fn t_975(df: u64) -> f64 {
    StudentsT::new(0.0, 1.0, df as f64)
        .expect("df ≥ 1 is a distribution")
        .inverse_cdf(0.975)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_value_has_no_spread_and_more_have_the_samples() {
        let mut running = Running::default();
        running.push(Some(2.0));
        let one = running.stats().unwrap();
        assert_eq!(
            (one.n, one.std, one.ci95),
            (1, None, None),
            "one sample: no spread to speak of"
        );
        running.push(Some(4.0));
        running.push(None);
        running.push(Some(f64::INFINITY));
        let stats = running.stats().unwrap();
        assert_eq!((stats.n, stats.mean, stats.min, stats.max), (2, 3.0, 2.0, 4.0));
        assert_eq!(stats.std, Some(2f64.sqrt()), "over n − 1");
    }

    #[test]
    fn the_interval_is_students() {
        // Tabulated t quantiles (two-sided 95 %).
        for (df, t) in [(1, 12.706), (4, 2.776), (9, 2.262), (29, 2.045), (1000, 1.962)] {
            assert!((t_975(df) - t).abs() < 1e-3, "df {df}: {}", t_975(df));
        }
        let mut running = Running::default();
        for x in [1.0, 2.0, 3.0, 4.0, 5.0] {
            running.push(Some(x));
        }
        let s = running.stats().unwrap();
        // sd √2.5, n 5: 2.776 · √2.5 / √5 = 1.963.
        assert!((s.ci95.unwrap() - 1.963).abs() < 1e-3, "{s:?}");
    }
}
