//! One-pass weighted moments of point pairs, shifted for precision, in parallel.
//!
//! Sums are taken of `a − c_a` and `b − c_b`, where the shifts `c` are the
//! means of an even sample of the rows: centring afterwards then cancels
//! little, since the shift lies within the spread of the data.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Rows per parallel work item.
const ROWS_PER_TASK: usize = 1 << 15;

/// Rows sampled to choose the shift.
const SHIFT_SAMPLES: usize = 64;

/// A read-only sequence of 3-D points, addressed by index or by range.
pub trait Rows: Sync {
    /// Iterator over a range of rows.
    type Iter<'a>: Iterator<Item = [f64; 3]>
    where
        Self: 'a;
    /// Number of points.
    fn n_rows(&self) -> usize;
    /// Point `i` (`i < n_rows()`).
    fn row(&self, i: usize) -> [f64; 3];
    /// Points `lo..hi` (`lo <= hi <= n_rows()`), in order.
    fn rows(&self, lo: usize, hi: usize) -> Self::Iter<'_>;
}

type VecRows<'a> =
    std::iter::Map<std::slice::Iter<'a, Vector3<f64>>, fn(&Vector3<f64>) -> [f64; 3]>;

fn vector_row(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl Rows for [Vector3<f64>] {
    type Iter<'a> = VecRows<'a>;
    #[inline(always)]
    fn n_rows(&self) -> usize {
        self.len()
    }
    #[inline(always)]
    fn row(&self, i: usize) -> [f64; 3] {
        vector_row(&self[i])
    }
    #[inline(always)]
    fn rows(&self, lo: usize, hi: usize) -> Self::Iter<'_> {
        self[lo..hi]
            .iter()
            .map(vector_row as fn(&Vector3<f64>) -> [f64; 3])
    }
}

impl Rows for Vec<Vector3<f64>> {
    type Iter<'a> = VecRows<'a>;
    #[inline(always)]
    fn n_rows(&self) -> usize {
        self.len()
    }
    #[inline(always)]
    fn row(&self, i: usize) -> [f64; 3] {
        self.as_slice().row(i)
    }
    #[inline(always)]
    fn rows(&self, lo: usize, hi: usize) -> Self::Iter<'_> {
        self.as_slice().rows(lo, hi)
    }
}

/// A flat row-major `(N, 3)` slice (length a multiple of 3).
pub(crate) struct FlatRows<'a>(pub &'a [f64]);

type FlatIter<'a> = std::iter::Map<std::slice::ChunksExact<'a, f64>, fn(&[f64]) -> [f64; 3]>;

fn flat_row(c: &[f64]) -> [f64; 3] {
    [c[0], c[1], c[2]]
}

impl Rows for FlatRows<'_> {
    type Iter<'a>
        = FlatIter<'a>
    where
        Self: 'a;
    #[inline(always)]
    fn n_rows(&self) -> usize {
        self.0.len() / 3
    }
    #[inline(always)]
    fn row(&self, i: usize) -> [f64; 3] {
        flat_row(&self.0[3 * i..3 * i + 3])
    }
    #[inline(always)]
    fn rows(&self, lo: usize, hi: usize) -> Self::Iter<'_> {
        self.0[3 * lo..3 * hi]
            .chunks_exact(3)
            .map(flat_row as fn(&[f64]) -> [f64; 3])
    }
}

/// Raw shifted sums of one block.
#[derive(Clone, Copy, Default)]
struct Sums {
    w: f64,
    a: [f64; 3],
    b: [f64; 3],
    aa: f64,
    bb: f64,
    ab: [[f64; 3]; 3],
}

impl Sums {
    fn add(mut self, o: Sums) -> Sums {
        self.w += o.w;
        self.aa += o.aa;
        self.bb += o.bb;
        for i in 0..3 {
            self.a[i] += o.a[i];
            self.b[i] += o.b[i];
            for j in 0..3 {
                self.ab[i][j] += o.ab[i][j];
            }
        }
        self
    }
}

/// Weighted moments of point pairs (source `a`, target `b`).
pub(crate) struct Moments {
    /// Number of pairs.
    pub n: usize,
    /// `W = Σ w`.
    pub weight_sum: f64,
    shift_a: Vector3<f64>,
    shift_b: Vector3<f64>,
    sums: Sums,
}

impl Moments {
    /// Accumulates over all pairs (`weights`: one per pair, or all 1).
    pub fn accumulate<A: Rows + ?Sized, B: Rows + ?Sized>(
        a: &A,
        b: &B,
        weights: Option<&[f64]>,
    ) -> Moments {
        let n = a.n_rows();
        let shift_a = sample_mean(a);
        let shift_b = sample_mean(b);
        let (ca, cb) = (
            [shift_a.x, shift_a.y, shift_a.z],
            [shift_b.x, shift_b.y, shift_b.z],
        );
        let sums = match weights {
            None => reduce(n, |lo, hi| block(a, b, &ca, &cb, lo, hi, |_| 1.0)),
            Some(w) => reduce(n, |lo, hi| block(a, b, &ca, &cb, lo, hi, |i| w[i])),
        };
        Moments {
            n,
            weight_sum: sums.w,
            shift_a,
            shift_b,
            sums,
        }
    }

    /// True when every sum is finite (no NaN/inf in the input, no overflow).
    pub fn is_finite(&self) -> bool {
        let s = &self.sums;
        s.w.is_finite()
            && s.aa.is_finite()
            && s.bb.is_finite()
            && s.a.iter().chain(&s.b).all(|v| v.is_finite())
            && s.ab.iter().flatten().all(|v| v.is_finite())
    }

    /// Weighted mean of the source points.
    pub fn mean_a(&self) -> Vector3<f64> {
        self.shift_a + Vector3::from(self.sums.a) / self.weight_sum
    }

    /// Weighted mean of the target points.
    pub fn mean_b(&self) -> Vector3<f64> {
        self.shift_b + Vector3::from(self.sums.b) / self.weight_sum
    }

    /// `Σ w·âᵢ b̂ᵢᵀ` with `â`, `b̂` centred on the weighted means
    /// (row index: source coordinate, column: target coordinate).
    pub fn centred_cross(&self) -> Matrix3<f64> {
        let s = &self.sums;
        Matrix3::from_fn(|i, j| s.ab[i][j] - s.a[i] * s.b[j] / s.w)
    }

    /// `Σ w·‖âᵢ‖²`.
    pub fn centred_aa(&self) -> f64 {
        let s = &self.sums;
        s.aa - Vector3::from(s.a).norm_squared() / s.w
    }

    /// `Σ w·‖b̂ᵢ‖²`.
    pub fn centred_bb(&self) -> f64 {
        let s = &self.sums;
        s.bb - Vector3::from(s.b).norm_squared() / s.w
    }
}

fn sample_mean<R: Rows + ?Sized>(r: &R) -> Vector3<f64> {
    let n = r.n_rows();
    if n == 0 {
        return Vector3::zeros();
    }
    let k = n.min(SHIFT_SAMPLES);
    let mut m = Vector3::zeros();
    let mut used = 0.0;
    for j in 0..k {
        let p = r.row(j * n / k);
        // Non-finite rows are reported later; keep the shift finite.
        if p.iter().all(|v| v.is_finite()) {
            m += Vector3::from(p);
            used += 1.0;
        }
    }
    if used > 0.0 {
        m / used
    } else {
        Vector3::zeros()
    }
}

fn reduce<F: Fn(usize, usize) -> Sums + Sync>(n: usize, f: F) -> Sums {
    if n <= ROWS_PER_TASK {
        return f(0, n);
    }
    let tasks = n.div_ceil(ROWS_PER_TASK);
    // One task per leaf: a thread that is descheduled on a busy machine then
    // holds back at most one block, the others are stolen.
    (0..tasks)
        .into_par_iter()
        .with_max_len(1)
        .map(|t| f(t * ROWS_PER_TASK, ((t + 1) * ROWS_PER_TASK).min(n)))
        .reduce(Sums::default, Sums::add)
}

#[inline(always)]
fn block<A: Rows + ?Sized, B: Rows + ?Sized, W: Fn(usize) -> f64>(
    a: &A,
    b: &B,
    ca: &[f64; 3],
    cb: &[f64; 3],
    lo: usize,
    hi: usize,
    weight: W,
) -> Sums {
    let mut s = Sums::default();
    for (i, (p, q)) in (lo..hi).zip(a.rows(lo, hi).zip(b.rows(lo, hi))) {
        let w = weight(i);
        let pa = [p[0] - ca[0], p[1] - ca[1], p[2] - ca[2]];
        let qb = [q[0] - cb[0], q[1] - cb[1], q[2] - cb[2]];
        let wp = [w * pa[0], w * pa[1], w * pa[2]];
        s.w += w;
        for k in 0..3 {
            s.a[k] += wp[k];
            s.b[k] += w * qb[k];
            for (acc, q) in s.ab[k].iter_mut().zip(&qb) {
                *acc += wp[k] * q;
            }
        }
        s.aa += wp[0] * pa[0] + wp[1] * pa[1] + wp[2] * pa[2];
        s.bb += w * (qb[0] * qb[0] + qb[1] * qb[1] + qb[2] * qb[2]);
    }
    s
}
