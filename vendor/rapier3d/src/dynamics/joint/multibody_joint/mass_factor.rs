//! Strider patch: the augmented mass matrices factorised along the multibody's tree.
//!
//! Entry `(i, j)` of a multibody's mass matrix (and of the augmented matrices built from
//! it: plus `dt` times the damping, `dt²` times the stiffness, the armature and, in one of
//! them, the `dt`-scaled Coriolis and gyroscopic terms) is zero unless dof `i` is dof
//! `j`'s ancestor, its descendant, or itself: a link's body Jacobian is zero outside its
//! own and its ancestors' columns. Eliminated leaves first (the dofs in decreasing order:
//! every dof comes after its ancestors), each pivot's column and row reach only its
//! ancestors, which are all coupled already, so the factors fill nothing in (Featherstone,
//! "Efficient factorization of the joint-space inertia matrix for branched kinematic
//! trees", IJRR 24(6), 2005, whose `LᵀDL` this is the unsymmetric form of: `A = P Q`, `P`
//! unit upper triangular, `Q` lower). For a four-legged robot of 18 dofs that is about
//! 650 multiply-adds a factorisation instead of a dense LU's 1,800, and about 200 a solve
//! instead of 300.
//!
//! The pivots are taken in that order, without row exchanges: the matrices are the
//! symmetric positive definite mass matrix plus a non-negative diagonal and, in one, the
//! small unsymmetric `dt`-scaled terms. A pivot that is not positive and finite, or has
//! lost all but a rounding error of its diagonal entry to the eliminations, makes the
//! factorisation fall back to nalgebra's pivoting LU of the same matrix, as does a
//! multibody with kinematic dofs (factorised as upstream: its leading block of the other
//! dofs, renumbered).

use crate::alloc_prelude::*;
use crate::math::Real;
use na::constraint::{SameNumberOfRows, ShapeConstraint};
use na::{DMatrix, Dim, Dyn, LU, Matrix, StorageMut};

/// Dofs of the buffers of one-column solves and of `Multibody::solve_jacobians`: more
/// take a heap buffer, or are solved one row at a time.
pub(crate) const MAX_DOFS: usize = 64;

/// AVX's mask that enables the first `k` of eight `f32` lanes (`k <= 8`), for the masked
/// loads and stores of the short runs here and in `multibody.rs`: a masked-off lane is
/// neither read nor written.
///
/// # Safety
/// The CPU must have AVX.
#[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
#[inline]
pub(crate) unsafe fn first_lanes(k: usize) -> core::arch::x86_64::__m256i {
    const MASKS: [i32; 16] = [-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0];
    assert!(k <= 8, "{k} lanes of 8");
    // SAFETY: entries `8 - k..16 - k` of `MASKS`, inside it; the CPU has AVX (the
    // caller's contract).
    unsafe { core::arch::x86_64::_mm256_loadu_si256(MASKS.as_ptr().add(8 - k).cast()) }
}

/// A factorised augmented mass matrix, solved with [`MassFactor::solve_mut`].
///
/// Dof `k`'s ancestors `c = chain(k)` (ascending) form a chain, so the ancestors of its
/// ancestor `c[t]` are `c[..t]`: each dof's entries of the factors are stored packed,
/// in the order of its chain, and eliminating `k` updates, for each `t`, the first `t`
/// entries of `c[t]`'s column and row, two contiguous runs.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Debug, Default)]
pub struct MassFactor {
    n: usize,
    /// `Some` when the matrix was factorised by nalgebra's pivoting LU instead.
    dense: Option<LU<Real, Dyn, Dyn>>,
    /// What `chains` were computed from: each link's ranges and own dofs, flattened.
    tree: Vec<usize>,
    /// Dof `k`'s ancestors, ascending: `chains[offsets[k]..offsets[k + 1]]`.
    offsets: Vec<usize>,
    chains: Vec<usize>,
    /// `P[c[t], k]` at `offsets[k] + t` (`c = chain(k)`): column `k` of the unit upper
    /// factor `P`, the multipliers.
    column: Vec<Real>,
    /// `Q[k, c[t]]` at `offsets[k] + t`: row `k` of the lower factor `Q`, left of its
    /// diagonal.
    row: Vec<Real>,
    /// `Q[k, k]`, the pivots.
    pivots: Vec<Real>,
}

impl Clone for MassFactor {
    fn clone(&self) -> Self {
        let mut copy = Self::default();
        copy.clone_from(self);
        copy
    }

    /// Into this factor's own buffers: the world is copied every few steps. The fields
    /// are named in full, so one added fails to compile rather than go uncopied.
    fn clone_from(&mut self, source: &Self) {
        let Self {
            n,
            dense,
            tree,
            offsets,
            chains,
            column,
            row,
            pivots,
        } = source;
        self.n = *n;
        self.dense.clone_from(dense);
        self.tree.clone_from(tree);
        self.offsets.clone_from(offsets);
        self.chains.clone_from(chains);
        self.column.clone_from(column);
        self.row.clone_from(row);
        self.pivots.clone_from(pivots);
    }
}

impl MassFactor {
    /// The factor of a `0 x 0` matrix.
    pub fn new() -> Self {
        Self::default()
    }

    /// The matrix's dimension.
    pub fn nrows(&self) -> usize {
        self.n
    }

    /// Whether the matrix was factorised along the tree (else by nalgebra's LU).
    pub fn is_tree(&self) -> bool {
        self.dense.is_none()
    }

    /// Factorises `matrix` with nalgebra's pivoting LU (a multibody with kinematic dofs).
    pub(crate) fn set_dense(&mut self, matrix: DMatrix<Real>) {
        self.n = matrix.nrows();
        self.dense = Some(LU::new(matrix));
    }

    /// Factorises `matrix` (`n x n`, the multibody's dofs in its assembly order) along the
    /// tree that `link_columns` and `link_dofs` describe: `link_columns[l]` is link `l`'s
    /// own and ancestors' dofs as ascending ranges, and `link_dofs[l]` its own dofs
    /// `(first, count)`, in dof order. Falls back to nalgebra's LU on a pivot that is not
    /// positive and finite, or not above a rounding error of its diagonal entry.
    pub(crate) fn set_tree(
        &mut self,
        matrix: &DMatrix<Real>,
        link_columns: &[Vec<(usize, usize)>],
        link_dofs: impl Iterator<Item = (usize, usize)> + Clone,
    ) {
        let n = matrix.nrows();
        self.n = n;
        self.dense = None;
        self.set_chains(n, link_columns, link_dofs);
        if !self.factorise(matrix) {
            self.dense = Some(LU::new(matrix.clone()));
        }
    }

    /// [`Self::set_tree`] along the tree `other` was last set along (the multibody's second
    /// matrix after its first): its chains copied where they differ, not compared link by
    /// link again.
    pub(crate) fn set_tree_as(&mut self, matrix: &DMatrix<Real>, other: &MassFactor) {
        let n = matrix.nrows();
        debug_assert_eq!(other.offsets.len(), n + 1, "another tree's chains");
        self.n = n;
        self.dense = None;
        if self.tree != other.tree || self.offsets.len() != other.offsets.len() {
            self.tree.clone_from(&other.tree);
            self.offsets.clone_from(&other.offsets);
            self.chains.clone_from(&other.chains);
        }
        if !self.factorise(matrix) {
            self.dense = Some(LU::new(matrix.clone()));
        }
    }

    /// Computes each dof's chain of ancestors, unless the tree is the one they were
    /// computed for (the same links, ranges and dofs as the last call's).
    fn set_chains(
        &mut self,
        n: usize,
        link_columns: &[Vec<(usize, usize)>],
        link_dofs: impl Iterator<Item = (usize, usize)> + Clone,
    ) {
        let mut same = self.offsets.len() == n + 1;
        let mut at = 0;
        for (columns, (first, count)) in link_columns.iter().zip(link_dofs.clone()) {
            // Link by link, a slice compared while the tree is the same (this runs twice
            // a step), then written.
            let len = 2 * columns.len() + 3;
            same = same
                && self.tree.get(at..at + len).is_some_and(|old| {
                    old.chunks_exact(2)
                        .zip(columns)
                        .all(|(o, &(s, l))| o[0] == s && o[1] == l)
                        && old[len - 3..] == [usize::MAX, first, count]
                });
            if !same {
                self.tree.truncate(at);
                for &(s, l) in columns {
                    self.tree.extend([s, l]);
                }
                self.tree.extend([usize::MAX, first, count]);
            }
            at += len;
        }
        if same && self.tree.len() == at {
            return;
        }
        self.tree.truncate(at);
        // Dof `k` of a link: the link's ranges cut short before `k` (its ancestors'
        // dofs, then its own joint's dofs before `k`). The links' dofs come in dof order
        // (assembly ids are given in link order).
        self.chains.clear();
        self.offsets.clear();
        self.offsets.push(0);
        for (columns, (first, count)) in link_columns.iter().zip(link_dofs) {
            debug_assert_eq!(first, self.offsets.len() - 1, "dofs out of order");
            for k in first..first + count {
                for &(s, len) in columns {
                    if s >= k {
                        break;
                    }
                    self.chains.extend(s..s + len.min(k - s));
                }
                self.offsets.push(self.chains.len());
            }
        }
        debug_assert_eq!(self.offsets.len(), n + 1, "a dof without a link");
        self.offsets.resize(n + 1, self.chains.len());
    }

    /// Dof `k`'s ancestors, ascending.
    #[cfg(test)]
    fn chain(&self, k: usize) -> &[usize] {
        &self.chains[self.offsets[k]..self.offsets[k + 1]]
    }

    /// Copies `matrix`'s entries into the packed factors and eliminates the dofs last
    /// first; `false` on a pivot that is not positive and finite, or not above a rounding
    /// error of its diagonal entry.
    fn factorise(&mut self, matrix: &DMatrix<Real>) -> bool {
        let a = matrix.as_slice();
        self.copy_entries(a);
        #[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX, checked just above.
            return unsafe { self.eliminate_avx(a) };
        }
        self.eliminate(a, sub_scaled_any)
    }

    /// The entries of `a` (column-major, `n x n`) on the tree's pattern into the packed
    /// factors, before their eliminations.
    fn copy_entries(&mut self, a: &[Real]) {
        let n = self.n;
        let total = self.chains.len();
        self.column.resize(total, 0.0);
        self.row.resize(total, 0.0);
        self.pivots.resize(n, 0.0);
        for k in 0..n {
            let (start, end) = (self.offsets[k], self.offsets[k + 1]);
            let a_k = &a[k * n..(k + 1) * n];
            let entries = self.chains[start..end]
                .iter()
                .zip(&mut self.column[start..end])
                .zip(&mut self.row[start..end]);
            for ((&i, column), row) in entries {
                *column = a_k[i];
                *row = a[i * n + k];
            }
            self.pivots[k] = a_k[k];
        }
    }

    /// [`Self::eliminate`] compiled for CPUs with AVX (no FMA: each entry's arithmetic is
    /// unchanged), its short runs through [`sub_scaled_avx`].
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
    #[target_feature(enable = "avx")]
    unsafe fn eliminate_avx(&mut self, a: &[Real]) -> bool {
        // SAFETY (of `sub_scaled_avx`): this function runs only where the CPU has AVX.
        self.eliminate(a, |y, x, s| unsafe { sub_scaled_avx(y, x, s) })
    }

    /// The eliminations of [`Self::factorise`], on the entries it copied from `a`, each run
    /// of a column or row updated by `sub_scaled`.
    #[inline(always)]
    fn eliminate(&mut self, a: &[Real], sub_scaled: impl Fn(&mut [Real], &[Real], Real)) -> bool {
        let n = self.n;
        for k in (0..n).rev() {
            let pivot = self.pivots[k];
            if !(pivot > a[k * n + k] * Real::EPSILON && pivot.is_finite()) {
                return false;
            }
            let (start, end) = (self.offsets[k], self.offsets[k + 1]);
            // The multipliers `P[i, k] = A[i, k] / Q[k, k]`.
            for l in &mut self.column[start..end] {
                *l /= pivot;
            }
            // Less `P[., k] Q[k, .]` over the ancestors' rows and columns: for the
            // chain's `t`-th dof `m`, whose own chain is the first `t`, its column's and
            // its row's entries and its pivot.
            let (before, from_k) = self.column.split_at_mut(start);
            let l = &from_k[..end - start];
            let (row_before, row_from_k) = self.row.split_at_mut(start);
            let u = &row_from_k[..end - start];
            for (t, &m) in self.chains[start..end].iter().enumerate() {
                let m_start = self.offsets[m];
                debug_assert_eq!(self.offsets[m + 1] - m_start, t);
                let (lt, ut) = (l[t], u[t]);
                sub_scaled(&mut before[m_start..m_start + t], &l[..t], ut);
                // `lt * u[j]`: the same product as `u[j] * lt` (IEEE multiplication
                // commutes bit for bit).
                sub_scaled(&mut row_before[m_start..m_start + t], &u[..t], lt);
                self.pivots[m] -= lt * ut;
            }
        }
        true
    }

    /// Solves `matrix x = b` in place for each column of `b` (`n` rows).
    ///
    /// # Panics
    /// If `b` has not `n` rows (as nalgebra's `LU::solve_mut`).
    pub fn solve_mut<R: Dim, C: Dim, S: StorageMut<Real, R, C>>(
        &self,
        b: &mut Matrix<Real, R, C, S>,
    ) where
        ShapeConstraint: SameNumberOfRows<R, Dyn>,
    {
        if let Some(lu) = &self.dense {
            let _ = lu.solve_mut(b);
            return;
        }
        let n = self.n;
        assert_eq!(
            b.nrows(),
            n,
            "a solve of {} rows by a factor of {n}",
            b.nrows()
        );
        if n == 0 {
            return;
        }
        // One column at a time through `solve_rows`, one lane wide: the same operations.
        let mut stack = [[0.0 as Real; 1]; MAX_DOFS];
        let mut heap = Vec::new();
        let x: &mut [[Real; 1]] = if n <= MAX_DOFS {
            &mut stack[..n]
        } else {
            heap.resize(n, [0.0]);
            &mut heap
        };
        for c in 0..b.ncols() {
            for (i, xi) in x.iter_mut().enumerate() {
                xi[0] = b[(i, c)];
            }
            self.solve_rows(x);
            for (i, xi) in x.iter().enumerate() {
                b[(i, c)] = xi[0];
            }
        }
    }

    /// Solves for several right-hand sides at once, row-interleaved (entry `i` of
    /// right-hand side `c` at `x[i][c]`, `x.len() == n`): each entry receives the
    /// operations [`Self::solve_mut`] gives it, in the same order, so the same bits, but
    /// the sides' independent chains side by side. `false` (and `x` untouched) when the
    /// factorisation is nalgebra's.
    #[inline(always)]
    pub(crate) fn solve_rows<const W: usize>(&self, x: &mut [[Real; W]]) -> bool {
        if self.dense.is_some() || x.len() != self.n {
            return false;
        }
        let n = self.n;
        // The eliminations, leaves first: `P y = b`.
        for k in (0..n).rev() {
            let (start, end) = (self.offsets[k], self.offsets[k + 1]);
            let xk: [Real; W] = x[k];
            for (&i, l) in self.chains[start..end].iter().zip(&self.column[start..end]) {
                let y = &mut x[i];
                for c in 0..W {
                    y[c] -= *l * xk[c];
                }
            }
        }
        // `Q x = y`, lower triangular in dof order.
        for k in 0..n {
            let (start, end) = (self.offsets[k], self.offsets[k + 1]);
            let (head, tail) = x.split_at_mut(k);
            let mut acc: [Real; W] = tail[0];
            for (&j, u) in self.chains[start..end].iter().zip(&self.row[start..end]) {
                let xj = &head[j];
                for c in 0..W {
                    acc[c] -= *u * xj[c];
                }
            }
            let d = self.pivots[k];
            for c in 0..W {
                tail[0][c] = acc[c] / d;
            }
        }
        true
    }
}

/// `y[i] -= x[i] * s` for each `i` (`x` as long as `y`), unfused.
#[inline(always)]
fn sub_scaled_any(y: &mut [Real], x: &[Real], s: Real) {
    for (y, x) in y.iter_mut().zip(x) {
        *y -= *x * s;
    }
}

/// [`sub_scaled_any`] eight entries at a time with AVX's masked loads and stores: the same
/// multiply then subtract, lane by lane (the runs are a tree's chains, a few entries each,
/// which the compiler's loop did one at a time).
///
/// # Safety
/// The CPU must have AVX.
#[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
#[target_feature(enable = "avx")]
#[inline]
unsafe fn sub_scaled_avx(y: &mut [Real], x: &[Real], s: Real) {
    use core::arch::x86_64::{
        _mm256_maskload_ps, _mm256_maskstore_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_sub_ps,
    };
    const LANES: usize = 8;
    let n = y.len();
    assert!(x.len() >= n);
    let scale = _mm256_set1_ps(s);
    let mut t = 0;
    while t < n {
        let k = (n - t).min(LANES);
        // SAFETY: the CPU has AVX (the caller's contract); the masked loads and stores
        // touch only the first `k` lanes, entries `t..t + k` of `y` and `x`, inside both.
        unsafe {
            let mask = first_lanes(k);
            let py = y.as_mut_ptr().add(t);
            let product = _mm256_mul_ps(_mm256_maskload_ps(x.as_ptr().add(t), mask), scale);
            let difference = _mm256_sub_ps(_mm256_maskload_ps(py, mask), product);
            _mm256_maskstore_ps(py, mask, difference);
        }
        t += k;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-legged tree: a free root (dofs 0-5), legs of three dofs at 6-8 and 9-11
    /// (hip of two dofs, knee of one: links 1, 2 and 3, 4).
    /// Each link's columns, and each link's own dofs.
    type Tree = (Vec<Vec<(usize, usize)>>, Vec<(usize, usize)>);

    fn tree() -> Tree {
        let columns = vec![
            vec![(0, 6)],
            vec![(0, 8)],
            vec![(0, 9)],
            vec![(0, 6), (9, 2)],
            vec![(0, 6), (9, 3)],
        ];
        let dofs = vec![(0, 6), (6, 2), (8, 1), (9, 2), (11, 1)];
        (columns, dofs)
    }

    fn coupled(columns: &[Vec<(usize, usize)>], i: usize, j: usize) -> bool {
        columns.iter().any(|c| {
            let has = |d: usize| c.iter().any(|&(s, l)| (s..s + l).contains(&d));
            has(i) && has(j)
        })
    }

    /// `B Bᵀ` over the tree's pattern (each link adding a block over its columns), a
    /// diagonal, and an unsymmetric part on the pattern: a mass matrix's structure.
    fn matrix(columns: &[Vec<(usize, usize)>], n: usize, seed: u32) -> DMatrix<Real> {
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as Real / (1u32 << 24) as Real - 0.5
        };
        let mut m = DMatrix::<Real>::zeros(n, n);
        for c in columns {
            let dofs: Vec<usize> = c.iter().flat_map(|&(s, l)| s..s + l).collect();
            let v: Vec<Real> = dofs.iter().map(|_| next()).collect();
            for (a, &i) in dofs.iter().enumerate() {
                for (b, &j) in dofs.iter().enumerate() {
                    m[(i, j)] += v[a] * v[b];
                }
            }
        }
        for i in 0..n {
            m[(i, i)] += 0.5 + next().abs();
            for j in 0..n {
                if i != j && coupled(columns, i, j) {
                    m[(i, j)] += 0.01 * next();
                }
            }
        }
        m
    }

    /// A factor set along another's tree solves bit for bit as one set along the tree
    /// itself, whatever tree it was set along before (here one with a leg fewer, whose
    /// chains are a prefix of the new ones, and the same tree again).
    #[test]
    fn a_factor_set_along_anothers_tree_solves_as_one_set_along_it() {
        let (columns, dofs) = tree();
        let (short_columns, short_dofs) = (&columns[..3], &dofs[..3]);
        let b = DMatrix::<Real>::from_fn(12, 3, |i, c| (i * 3 + c) as Real - 7.0);
        for seed in 0..10 {
            let (m1, m2) = (matrix(&columns, 12, seed), matrix(&columns, 12, seed + 100));
            let mut first = MassFactor::new();
            first.set_tree(&m1, &columns, dofs.iter().copied());
            let mut alone = MassFactor::new();
            alone.set_tree(&m2, &columns, dofs.iter().copied());
            let mut short = MassFactor::new();
            let m_short = matrix(short_columns, 9, seed);
            short.set_tree(&m_short, short_columns, short_dofs.iter().copied());
            let mut again = alone.clone();
            // And `set_tree` itself on a factor last set along the shorter tree.
            let mut regrown = short.clone();
            regrown.set_tree(&m2, &columns, dofs.iter().copied());
            let (mut x, mut y) = (b.clone(), b.clone());
            regrown.solve_mut(&mut x);
            alone.solve_mut(&mut y);
            assert!(
                x.iter()
                    .zip(y.iter())
                    .all(|(p, q)| p.to_bits() == q.to_bits())
            );
            for second in [&mut MassFactor::new(), &mut short, &mut again] {
                second.set_tree_as(&m2, &first);
                assert!(second.is_tree());
                let (mut x, mut y) = (b.clone(), b.clone());
                second.solve_mut(&mut x);
                alone.solve_mut(&mut y);
                assert!(
                    x.iter()
                        .zip(y.iter())
                        .all(|(p, q)| p.to_bits() == q.to_bits())
                );
            }
        }
    }

    /// The eliminations give the same bits with AVX's masked runs as without, on chains
    /// longer than a register (a leg of five dofs under the free root: chains of up to 10).
    #[cfg(all(feature = "std", feature = "f32", target_arch = "x86_64"))]
    #[test]
    fn eliminations_are_the_same_with_avx() {
        if !std::is_x86_feature_detected!("avx") {
            return;
        }
        let columns = vec![
            vec![(0, 6)],
            vec![(0, 8)],
            vec![(0, 9)],
            vec![(0, 11)],
            vec![(0, 6), (11, 2)],
        ];
        let dofs = vec![(0, 6), (6, 2), (8, 1), (9, 2), (11, 2)];
        let bits = |v: &[Real]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for seed in 0..20 {
            let m = matrix(&columns, 13, seed);
            let mut avx = MassFactor::new();
            avx.set_tree(&m, &columns, dofs.iter().copied());
            assert!(avx.is_tree());
            let mut portable = avx.clone();
            portable.copy_entries(m.as_slice());
            assert!(portable.eliminate(m.as_slice(), sub_scaled_any));
            assert_eq!(bits(&avx.column), bits(&portable.column), "seed {seed}");
            assert_eq!(bits(&avx.row), bits(&portable.row), "seed {seed}");
            assert_eq!(bits(&avx.pivots), bits(&portable.pivots), "seed {seed}");
        }
        // And a run of each length against the loop, at a register's edge too.
        for n in 0..=17 {
            let x: Vec<Real> = (0..n).map(|i| i as Real * 0.37 - 2.1).collect();
            let start: Vec<Real> = (0..n).map(|i| 1.3 - i as Real * 0.11).collect();
            let (mut a, mut b) = (start.clone(), start.clone());
            sub_scaled_any(&mut a, &x, 0.713);
            // SAFETY: the CPU has AVX, checked above.
            unsafe { sub_scaled_avx(&mut b, &x, 0.713) };
            assert_eq!(bits(&a), bits(&b), "{n} entries");
            assert!(n < 2 || bits(&a) != bits(&start));
        }
    }

    #[test]
    fn tree_solves_agree_with_dense_lu() {
        let (columns, dofs) = tree();
        for seed in 0..50 {
            let m = matrix(&columns, 12, seed);
            let mut factor = MassFactor::new();
            factor.set_tree(&m, &columns, dofs.iter().copied());
            assert!(factor.is_tree());
            let b = DMatrix::<Real>::from_fn(12, 3, |i, c| (i * 3 + c) as Real - 7.0);
            let mut x = b.clone();
            factor.solve_mut(&mut x);
            let expected = LU::new(m.clone()).solve(&b).unwrap();
            let residual = (&m * &x - &b).abs().max();
            assert!(residual < 1e-4, "seed {seed}: residual {residual}");
            assert!((&x - &expected).abs().max() < 1e-3 * expected.abs().max().max(1.0));
        }
    }

    #[test]
    fn rows_solved_together_match_one_by_one_bit_for_bit() {
        let (columns, dofs) = tree();
        let m = matrix(&columns, 12, 7);
        let mut factor = MassFactor::new();
        factor.set_tree(&m, &columns, dofs.iter().copied());
        let mut rows = [[0.0 as Real; 12]; 12];
        for (i, row) in rows.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = ((i * 7 + c * 3) % 11) as Real * 0.37 - 1.5;
            }
        }
        let mut together = rows;
        assert!(factor.solve_rows(&mut together));
        for c in 0..12 {
            let mut one = na::DVector::<Real>::from_fn(12, |i, _| rows[i][c]);
            factor.solve_mut(&mut one);
            for i in 0..12 {
                assert_eq!(
                    one[i].to_bits(),
                    together[i][c].to_bits(),
                    "entry {i} of {c}"
                );
            }
        }
    }

    #[test]
    fn a_pivot_that_is_not_positive_falls_back_to_the_pivoting_lu() {
        let (columns, dofs) = tree();
        let mut m = matrix(&columns, 12, 3);
        // A leaf whose pivot is zero: nalgebra's LU exchanges rows, the tree cannot.
        m[(11, 11)] = 0.0;
        let mut factor = MassFactor::new();
        factor.set_tree(&m, &columns, dofs.iter().copied());
        assert!(!factor.is_tree());
        let b = DMatrix::<Real>::from_fn(12, 1, |i, _| i as Real);
        let mut x = b.clone();
        factor.solve_mut(&mut x);
        assert_eq!(x, LU::new(m).solve(&b).unwrap());
    }

    #[test]
    fn the_factors_multiply_back_to_the_matrix() {
        let (columns, dofs) = tree();
        let n = 12;
        let m = matrix(&columns, n, 11);
        let mut factor = MassFactor::new();
        factor.set_tree(&m, &columns, dofs.iter().copied());
        assert!(factor.is_tree());
        let mut p = DMatrix::<Real>::identity(n, n);
        let mut q = DMatrix::<Real>::zeros(n, n);
        for k in 0..n {
            let start = factor.offsets[k];
            for (t, &i) in factor.chain(k).iter().enumerate() {
                p[(i, k)] = factor.column[start + t];
                q[(k, i)] = factor.row[start + t];
            }
            q[(k, k)] = factor.pivots[k];
        }
        let diff = (&p * &q - &m).amax();
        assert!(diff <= 1e-5 * m.amax(), "P Q differs from A by {diff}");
        // Dof 10 (the second leg's hip) has the root's six and dof 9 above it.
        assert_eq!(factor.chain(10), &[0, 1, 2, 3, 4, 5, 9]);
        assert_eq!(factor.chain(6), &[0, 1, 2, 3, 4, 5]);
        assert_eq!(factor.chain(0), &[] as &[usize]);
    }
}
