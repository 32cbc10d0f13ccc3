//! The one piece of linear algebra the beamformers need: solving a small Hermitian positive
//! definite system (a covariance matrix, at most 8 x 8) by Cholesky factorization.

use rustfft::num_complex::Complex;

/// Solves `A x = b` for Hermitian positive definite `n x n` matrices `A`, reusing its storage.
#[derive(Debug, Clone)]
pub(crate) struct HermitianSolver {
    n: usize,
    /// The lower triangular factor `L` of `A = L Lᴴ`, row-major.
    l: Vec<Complex<f64>>,
}

impl HermitianSolver {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            n,
            l: vec![Complex::default(); n * n],
        }
    }

    /// `x` such that `a x = b`, with `a` row-major `n x n` (only its lower triangle is read), `b`
    /// and `x` of length `n`. False, with `x` unspecified, when `a` is not positive definite (or
    /// not finite).
    #[must_use]
    pub(crate) fn solve(
        &mut self,
        a: &[Complex<f64>],
        b: &[Complex<f64>],
        x: &mut [Complex<f64>],
    ) -> bool {
        let n = self.n;
        let l = &mut self.l;
        for j in 0..n {
            let d = a[j * n + j].re - (0..j).map(|k| l[j * n + k].norm_sqr()).sum::<f64>();
            if !(d > 0.0 && d.is_finite()) {
                return false;
            }
            let pivot = d.sqrt();
            l[j * n + j] = Complex::new(pivot, 0.0);
            for i in j + 1..n {
                let s: Complex<f64> = (0..j).map(|k| l[i * n + k] * l[j * n + k].conj()).sum();
                l[i * n + j] = (a[i * n + j] - s) / pivot;
            }
        }
        // L y = b, then Lᴴ x = y (y kept in x).
        for i in 0..n {
            let s: Complex<f64> = (0..i).map(|k| l[i * n + k] * x[k]).sum();
            x[i] = (b[i] - s) / l[i * n + i].re;
        }
        for i in (0..n).rev() {
            let s: Complex<f64> = (i + 1..n).map(|k| l[k * n + i].conj() * x[k]).sum();
            x[i] = (x[i] - s) / l[i * n + i].re;
        }
        true
    }
}
