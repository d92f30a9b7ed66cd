//! The RBF kernel with the median bandwidth (spec `algorithms.md` §1.2 step 2).

/// Pairwise kernel matrix `k(x_n, x_m) = exp(−‖x_n − x_m‖²/h)` and its bandwidth `h`.
#[derive(Debug, Clone)]
pub struct RbfKernel {
    /// `N×N` row-major kernel values.
    pub k: Vec<f64>,
    /// The bandwidth `h = med²/ln N + 1e-9`.
    pub bandwidth: f64,
    /// Number of particles.
    pub n: usize,
}

/// Median of a slice, numpy-style (mean of the two middle values for even lengths).
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(|a, b| a.total_cmp(b));
    let l = values.len();
    if l % 2 == 1 {
        values[l / 2]
    } else {
        0.5 * (values[l / 2 - 1] + values[l / 2])
    }
}

impl RbfKernel {
    /// The kernel over `particles` (each a flat trajectory, slacks excluded).
    pub fn new(particles: &[Vec<f64>]) -> Self {
        let n = particles.len();
        let mut d2 = vec![0.0; n * n];
        let mut upper = Vec::with_capacity(n * n.saturating_sub(1) / 2);
        for i in 0..n {
            for j in i + 1..n {
                let s: f64 = particles[i]
                    .iter()
                    .zip(&particles[j])
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum();
                d2[i * n + j] = s;
                d2[j * n + i] = s;
                upper.push(s.sqrt());
            }
        }
        let med = median(&mut upper);
        // With one particle there is no spread to measure; any bandwidth gives k = 1.
        let bandwidth = if n > 1 {
            med * med / (n as f64).ln() + 1e-9
        } else {
            1.0
        };
        let k = d2.iter().map(|&v| (-v / bandwidth).exp()).collect();
        Self { k, bandwidth, n }
    }

    /// `k(x_a, x_b)`.
    pub fn at(&self, a: usize, b: usize) -> f64 {
        self.k[a * self.n + b]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_is_numpy_style() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    #[test]
    fn kernel_uses_median_bandwidth() {
        let p = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 2.0]];
        let k = RbfKernel::new(&p);
        // Distances 1, 2, sqrt(5): median 2, h = 4/ln 3.
        let h = 4.0 / 3f64.ln() + 1e-9;
        assert!((k.bandwidth - h).abs() < 1e-12);
        assert!((k.at(0, 1) - (-1.0 / h).exp()).abs() < 1e-12);
        assert_eq!(k.at(2, 2), 1.0);
    }
}
