//! Gaussian factors in information form and one step of multifrontal Cholesky elimination.
//!
//! A linearised factor `‖A·δ − b‖²` over variables `k₁ … kₙ` is kept as its augmented
//! information matrix `[A b]ᵀ[A b] = [H g; gᵀ f]`, so factors over the same variables add
//! and eliminating a variable is a partial Cholesky factorisation followed by a Schur
//! complement (Kaess et al., "iSAM2", IJRR 31(2), 2012, §3; Dellaert and Kaess, "Factor
//! Graphs for Robot Perception", 2017, §3.3 and §6, the Cholesky variant GTSAM's iSAM2
//! uses by default).

use nalgebra::{DMatrix, DVector};

/// `½‖A·δ − b‖²` in augmented information form over `keys` (internal variable indices),
/// the last row and column holding `g = Aᵀb` and `f = bᵀb`.
#[derive(Debug, Clone)]
pub(crate) struct InfoFactor {
    pub(crate) keys: Vec<usize>,
    pub(crate) dims: Vec<usize>,
    pub(crate) aug: DMatrix<f64>,
}

impl InfoFactor {
    /// From a whitened Jacobian `[A₁ … Aₙ]` (columns in `keys` order, `dims` wide) and `b`.
    pub(crate) fn from_jacobian(
        keys: Vec<usize>,
        dims: Vec<usize>,
        a: &DMatrix<f64>,
        b: &DVector<f64>,
    ) -> Self {
        let n = a.ncols();
        let mut ab = DMatrix::zeros(a.nrows(), n + 1);
        ab.columns_mut(0, n).copy_from(a);
        ab.column_mut(n).copy_from(b);
        Self {
            keys,
            dims,
            aug: ab.tr_mul(&ab),
        }
    }

    /// `bᵀb`: twice the factor's error at the linearisation point.
    pub(crate) fn constant(&self) -> f64 {
        let n = self.aug.nrows() - 1;
        self.aug[(n, n)]
    }
}

/// A variable eliminated: `R·δ_v + S·δ_sep = d`, with `R` upper triangular.
#[derive(Debug, Clone)]
pub(crate) struct Conditional {
    pub(crate) r: DMatrix<f64>,
    pub(crate) s: DMatrix<f64>,
    pub(crate) d: DVector<f64>,
}

impl Conditional {
    /// The frontal variables' values given the separator's, stacked in the conditional's
    /// order, written into `out` (resized; no allocation once it is large enough).
    pub(crate) fn solve_into(&self, sep: &DVector<f64>, out: &mut DVector<f64>) {
        out.resize_vertically_mut(self.d.len(), 0.0);
        out.copy_from(&self.d);
        if !sep.is_empty() {
            out.gemv(-1.0, &self.s, sep, 1.0);
        }
        if !self.r.solve_upper_triangular_mut(out) {
            out.fill(0.0);
        }
    }

    #[cfg(test)]
    fn solve(&self, sep: &DVector<f64>) -> DVector<f64> {
        let mut out = DVector::zeros(0);
        self.solve_into(sep, &mut out);
        out
    }
}

/// Why elimination failed: the variable's information block is not positive definite
/// (an unconstrained direction, e.g. a pose graph without a prior).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Indeterminate;

/// Sums `factors` over `keys` (the frontal variable first; every key of every factor must
/// be among `keys`) into one augmented information matrix, block by block.
pub(crate) fn combine(keys: &[usize], dims: &[usize], factors: &[&InfoFactor]) -> DMatrix<f64> {
    let mut offset = Vec::with_capacity(keys.len() + 1);
    let mut n = 0;
    for &d in dims {
        offset.push(n);
        n += d;
    }
    let mut m = DMatrix::zeros(n + 1, n + 1);
    // (our offset, its offset, width) of each of the factor's blocks, its last row and
    // column (g and f) as a block of width 1 mapped onto ours.
    let mut blocks: Vec<(usize, usize, usize)> = Vec::with_capacity(8);
    for f in factors {
        blocks.clear();
        let mut at = 0;
        for (&k, &d) in f.keys.iter().zip(&f.dims) {
            if let Some(i) = keys.iter().position(|&x| x == k) {
                blocks.push((offset[i], at, d));
            }
            at += d;
        }
        blocks.push((n, at, 1));
        for &(mc, fc, wc) in &blocks {
            for &(mr, fr, wr) in &blocks {
                let mut target = m.view_mut((mr, mc), (wr, wc));
                target += f.aug.view((fr, fc), (wr, wc));
            }
        }
    }
    m
}

/// Eliminates the first `d` dimensions of an augmented information matrix: the
/// conditional on them and the marginal (Schur complement) on the rest, in augmented form.
/// `m` is consumed: the Schur complement is formed in place.
pub(crate) fn eliminate(
    mut m: DMatrix<f64>,
    d: usize,
) -> Result<(Conditional, DMatrix<f64>), Indeterminate> {
    let n = m.nrows();
    let rest = n - d;
    let chol = m
        .view((0, 0), (d, d))
        .clone_owned()
        .cholesky()
        .ok_or(Indeterminate)?;
    let l = chol.l();
    // X = L⁻¹·[H_vs g_v], in place: the conditional's S and d in one triangular solve.
    if !l.solve_lower_triangular_mut(&mut m.view_mut((0, d), (d, rest))) {
        return Err(Indeterminate);
    }
    let x = copy_block(&m, 0, d, d, rest);
    // Schur complement H_ss − XᵀX on the trailing block (a blocked product).
    let xt = x.transpose();
    m.view_mut((d, d), (rest, rest)).gemm(-1.0, &xt, &x, 1.0);
    let marginal = copy_block(&m, d, d, rest, rest);
    let sep = rest - 1;
    let conditional = Conditional {
        r: l.transpose(),
        s: x.columns(0, sep).clone_owned(),
        d: x.column(sep).clone_owned(),
    };
    Ok((conditional, marginal))
}

/// The `rows × cols` block of `m` at (`row`, `col`), copied a column (a contiguous run of
/// column-major storage) at a time.
fn copy_block(m: &DMatrix<f64>, row: usize, col: usize, rows: usize, cols: usize) -> DMatrix<f64> {
    let stride = m.nrows();
    let src = m.as_slice();
    let mut out = Vec::with_capacity(rows * cols);
    for c in col..col + cols {
        out.extend_from_slice(&src[c * stride + row..c * stride + row + rows]);
    }
    DMatrix::from_vec(rows, cols, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eliminating_then_solving_matches_the_dense_solution() {
        // Guards the sign conventions of g and S: H·δ = g solved by elimination equals
        // the direct solve.
        let a = DMatrix::from_row_slice(
            5,
            4,
            &[
                2.0, 0.5, 0.0, 1.0, //
                0.0, 1.5, -1.0, 0.0, //
                1.0, 0.0, 3.0, 0.5, //
                0.0, -0.5, 0.0, 2.0, //
                0.3, 0.2, 0.1, 0.4,
            ],
        );
        let b = DVector::from_row_slice(&[1.0, -2.0, 0.5, 3.0, 0.1]);
        let f = InfoFactor::from_jacobian(vec![7, 9], vec![2, 2], &a, &b);
        let m = combine(&[7, 9], &[2, 2], &[&f]);
        let (c1, marginal) = eliminate(m, 2).expect("first");
        let (c2, rest) = eliminate(marginal, 2).expect("second");
        let x2 = c2.solve(&DVector::zeros(0));
        let x1 = c1.solve(&x2);
        let direct = (a.transpose() * &a)
            .cholesky()
            .expect("pd")
            .solve(&(a.transpose() * &b));
        assert!((x1 - direct.rows(0, 2)).norm() < 1e-12);
        assert!((x2 - direct.rows(2, 2)).norm() < 1e-12);
        // What is left is the least-squares residual ‖A·δ* − b‖².
        let residual = (&a * &direct - &b).norm_squared();
        assert!((rest[(0, 0)] - residual).abs() < 1e-12);
    }
}
