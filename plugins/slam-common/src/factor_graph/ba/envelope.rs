//! The reduced camera system's matrix: symmetric 6×6 blocks within an envelope (skyline),
//! and its Cholesky factorisation without fill outside it.

use super::*;

/// A symmetric block matrix (6×6 blocks) stored by its upper triangle within an envelope:
/// block column `i` holds the blocks of rows `first[i]..=i` contiguously (slot `(i, j)` is
/// block `(j, i)`, `j ≤ i`). [`Envelope::factor`] overwrites it with the upper Cholesky
/// factor `R` (`S = Rᵀ R`), which has no fill outside the envelope.
#[derive(Debug, Clone)]
pub(super) struct Envelope {
    pub(super) first: Vec<usize>,
    pub(super) start: Vec<usize>,
    pub(super) blocks: Vec<Matrix6<f64>>,
    /// `R_ii⁻¹` after factorisation.
    pub(super) inv_diag: Vec<Matrix6<f64>>,
}

impl Envelope {
    pub(super) fn new(first: Vec<usize>) -> Self {
        let mut start = Vec::with_capacity(first.len() + 1);
        start.push(0);
        for (i, &f) in first.iter().enumerate() {
            debug_assert!(f <= i);
            start.push(start[i] + i + 1 - f);
        }
        let total = start[first.len()];
        Self {
            inv_diag: vec![Matrix6::zeros(); first.len()],
            blocks: vec![Matrix6::zeros(); total],
            first,
            start,
        }
    }

    pub(super) fn index(&self, i: usize, j: usize) -> usize {
        debug_assert!(
            self.first[i] <= j && j <= i,
            "({i}, {j}) outside the envelope"
        );
        self.start[i] + j - self.first[i]
    }

    /// Block `(j, i)`, `j ≤ i`, of the upper triangle.
    pub(super) fn block_mut(&mut self, i: usize, j: usize) -> &mut Matrix6<f64> {
        let k = self.index(i, j);
        &mut self.blocks[k]
    }

    pub(super) fn clear(&mut self) {
        self.blocks.fill(Matrix6::zeros());
    }

    /// Cholesky factorisation in place, column by column (`R_ji = R_jj⁻ᵀ (S_ji − Σ_{k<j}
    /// R_kjᵀ R_ki)`); false if the matrix is not positive definite.
    pub(super) fn factor(&mut self) -> bool {
        for i in 0..self.first.len() {
            let fi = self.first[i];
            let col_i = self.start[i];
            for j in fi..i {
                let fj = self.first[j];
                let col_j = self.start[j];
                let mut acc = self.blocks[col_i + j - fi];
                for k in fi.max(fj)..j {
                    acc -= self.blocks[col_j + k - fj].tr_mul(&self.blocks[col_i + k - fi]);
                }
                self.blocks[col_i + j - fi] = self.inv_diag[j].tr_mul(&acc);
            }
            let mut acc = self.blocks[col_i + i - fi];
            for r in &self.blocks[col_i..col_i + i - fi] {
                acc -= r.tr_mul(r);
            }
            let Some(chol) = Cholesky::new(acc) else {
                return false;
            };
            let l = chol.l();
            let Some(l_inv) = l.solve_lower_triangular(&Matrix6::identity()) else {
                return false;
            };
            self.blocks[col_i + i - fi] = l.transpose();
            self.inv_diag[i] = l_inv.transpose();
        }
        true
    }

    /// Solves `Rᵀ R x = b` in place after [`Envelope::factor`].
    pub(super) fn solve(&self, b: &mut [Vector6<f64>]) {
        let n = self.first.len();
        for i in 0..n {
            let fi = self.first[i];
            let mut acc = b[i];
            for (r, y) in self.blocks[self.start[i]..self.start[i] + i - fi]
                .iter()
                .zip(&b[fi..i])
            {
                acc -= r.tr_mul(y);
            }
            b[i] = self.inv_diag[i].tr_mul(&acc);
        }
        for i in (0..n).rev() {
            let fi = self.first[i];
            let x = self.inv_diag[i] * b[i];
            b[i] = x;
            for (r, y) in self.blocks[self.start[i]..self.start[i] + i - fi]
                .iter()
                .zip(&mut b[fi..i])
            {
                *y -= r * x;
            }
        }
    }
}
