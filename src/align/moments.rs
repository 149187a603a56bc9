//! One-pass weighted moments of point pairs, shifted for precision, in parallel.
//!
//! Sums are taken of `a − c_a` and of the residuals `d` of `b − c_b` under a
//! prior guess of the transform (fitted on a sample of the pairs), where the
//! shifts `c` are the means of an even sample of the rows: centring afterwards
//! then cancels little, since the shift lies within the spread of the data, and
//! the residual sum of squares of the final fit follows from small terms.

use crate::simd::Isa;
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
    /// The rows as one flat row-major slice (`[x0, y0, z0, x1, …]`) when
    /// stored so: the accumulation then takes its vectorised path.
    fn flat(&self) -> Option<&[f64]> {
        None
    }
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
    fn flat(&self) -> Option<&[f64]> {
        Some(self.0)
    }
}

/// Raw shifted sums of one block: `a' = a − c_a` and the residuals of the
/// prior guess, `d = (b − c_b) − (M₀·a' + t₀)` (plain `b − c_b` without one).
#[derive(Clone, Copy, Default)]
struct Sums {
    w: f64,
    a: [f64; 3],
    d: [f64; 3],
    /// Upper triangle of `Σ w·a'a'ᵀ`: xx, xy, xz, yy, yz, zz.
    aa: [f64; 6],
    /// `Σ w·‖d‖²`.
    dd: f64,
    /// `Σ w·a'dᵀ` (row: source coordinate, column: target coordinate).
    ad: [[f64; 3]; 3],
}

impl Sums {
    fn add(mut self, o: Sums) -> Sums {
        self.w += o.w;
        self.dd += o.dd;
        for i in 0..3 {
            self.a[i] += o.a[i];
            self.d[i] += o.d[i];
            for j in 0..3 {
                self.ad[i][j] += o.ad[i][j];
            }
        }
        for (x, y) in self.aa.iter_mut().zip(o.aa) {
            *x += y;
        }
        self
    }
}

/// A guess of the transform, `b ≈ m·a + t` (`m = s·R`), that the moments are
/// taken relative to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prior {
    /// `s·R`.
    pub m: Matrix3<f64>,
    /// Translation.
    pub t: Vector3<f64>,
}

/// Weighted moments of point pairs (source `a`, target `b`), relative to the
/// shifts and to a prior guess of the transform: with a close guess every
/// second moment of the residuals is small, so the residual sum of squares of
/// the final fit comes out of the moments without cancellation.
pub(crate) struct Moments {
    /// Number of pairs.
    pub n: usize,
    /// `W = Σ w`.
    pub weight_sum: f64,
    shift_a: Vector3<f64>,
    shift_b: Vector3<f64>,
    /// The prior in shifted coordinates: `d = b' − (m0·a' + t0)`.
    m0: Matrix3<f64>,
    t0: Vector3<f64>,
    sums: Sums,
}

impl Moments {
    /// Accumulates over all pairs (`weights`: one per pair, or all 1),
    /// relative to `prior` (none: the zero map).
    pub fn accumulate<A: Rows + ?Sized, B: Rows + ?Sized>(
        a: &A,
        b: &B,
        weights: Option<&[f64]>,
        prior: Option<&Prior>,
    ) -> Moments {
        let n = a.n_rows();
        let shift_a = sample_mean(a);
        let shift_b = sample_mean(b);
        // b' = b − c_b ≈ m·(a' + c_a) + t − c_b = m·a' + (m·c_a + t − c_b).
        let (m0, t0) = match prior {
            Some(p) => (p.m, p.m * shift_a + p.t - shift_b),
            None => (Matrix3::zeros(), Vector3::zeros()),
        };
        let k = MomentKernel {
            ca: shift_a.into(),
            cb: shift_b.into(),
            m: [
                [m0[(0, 0)], m0[(0, 1)], m0[(0, 2)]],
                [m0[(1, 0)], m0[(1, 1)], m0[(1, 2)]],
                [m0[(2, 0)], m0[(2, 1)], m0[(2, 2)]],
            ],
            t: t0.into(),
        };
        let sums = match (a.flat(), b.flat(), weights) {
            (Some(fa), Some(fb), None) => reduce(n, |lo, hi| k.flat_block(fa, fb, None, lo, hi)),
            (Some(fa), Some(fb), Some(w)) => {
                reduce(n, |lo, hi| k.flat_block(fa, fb, Some(w), lo, hi))
            }
            (_, _, None) => reduce(n, |lo, hi| k.block(a, b, lo, hi, |_| 1.0)),
            (_, _, Some(w)) => reduce(n, |lo, hi| k.block(a, b, lo, hi, |i| w[i])),
        };
        Moments {
            n,
            weight_sum: sums.w,
            shift_a,
            shift_b,
            m0,
            t0,
            sums,
        }
    }

    /// Empty running moments shifted to `(shift_a, shift_b)` (a first pair,
    /// or any point near the data), without a prior: pairs are added one at a
    /// time with [`Moments::push_weighted`], each in O(1).
    pub fn running(shift_a: Vector3<f64>, shift_b: Vector3<f64>) -> Moments {
        Moments {
            n: 0,
            weight_sum: 0.0,
            shift_a,
            shift_b,
            m0: Matrix3::zeros(),
            t0: Vector3::zeros(),
            sums: Sums::default(),
        }
    }

    /// Adds the pair `(a, b)` with weight `w` (the terms
    /// [`Moments::accumulate`] sums for a pair of that weight, relative to this
    /// accumulator's shifts and prior).
    pub fn push_weighted(&mut self, a: &Vector3<f64>, b: &Vector3<f64>, w: f64) {
        self.add_weighted(a, b, w);
        self.n += 1;
    }

    /// Takes out a pair that [`Moments::push_weighted`] added with weight `w`.
    pub fn pull_weighted(&mut self, a: &Vector3<f64>, b: &Vector3<f64>, w: f64) {
        self.add_weighted(a, b, -w);
        self.n = self.n.saturating_sub(1);
    }

    fn add_weighted(&mut self, a: &Vector3<f64>, b: &Vector3<f64>, w: f64) {
        let k = MomentKernel {
            ca: self.shift_a.into(),
            cb: self.shift_b.into(),
            m: [
                [self.m0[(0, 0)], self.m0[(0, 1)], self.m0[(0, 2)]],
                [self.m0[(1, 0)], self.m0[(1, 1)], self.m0[(1, 2)]],
                [self.m0[(2, 0)], self.m0[(2, 1)], self.m0[(2, 2)]],
            ],
            t: self.t0.into(),
        };
        let one = [*a];
        let other = [*b];
        let s = k.block(&one[..], &other[..], 0, 1, |_| w);
        self.sums = self.sums.add(s);
        self.weight_sum = self.sums.w;
    }

    /// True when every sum is finite (no NaN/inf in the input, no overflow).
    pub fn is_finite(&self) -> bool {
        let s = &self.sums;
        s.w.is_finite()
            && s.dd.is_finite()
            && s.a.iter().chain(&s.d).chain(&s.aa).all(|v| v.is_finite())
            && s.ad.iter().flatten().all(|v| v.is_finite())
    }

    fn sum_a(&self) -> Vector3<f64> {
        Vector3::from(self.sums.a)
    }

    fn sum_d(&self) -> Vector3<f64> {
        Vector3::from(self.sums.d)
    }

    /// Weighted mean of the source points.
    pub fn mean_a(&self) -> Vector3<f64> {
        self.shift_a + self.sum_a() / self.weight_sum
    }

    /// Weighted mean of the target points.
    pub fn mean_b(&self) -> Vector3<f64> {
        let w = self.weight_sum;
        self.shift_b + self.m0 * (self.sum_a() / w) + self.t0 + self.sum_d() / w
    }

    /// `Σ w·âᵢâᵢᵀ`, centred on the weighted mean.
    fn centred_aa_matrix(&self) -> Matrix3<f64> {
        let s = &self.sums;
        let q = &s.aa;
        let raw = Matrix3::new(q[0], q[1], q[2], q[1], q[3], q[4], q[2], q[4], q[5]);
        raw - self.sum_a() * self.sum_a().transpose() / s.w
    }

    /// `Σ w·âᵢd̂ᵢᵀ`, centred.
    fn centred_ad(&self) -> Matrix3<f64> {
        let s = &self.sums;
        Matrix3::from_fn(|i, j| s.ad[i][j] - s.a[i] * s.d[j] / s.w)
    }

    /// `Σ w·‖d̂ᵢ‖²`, centred.
    fn centred_dd(&self) -> f64 {
        self.sums.dd - self.sum_d().norm_squared() / self.sums.w
    }

    /// `Σ w·âᵢ b̂ᵢᵀ` with `â`, `b̂` centred on the weighted means
    /// (row index: source coordinate, column: target coordinate).
    pub fn centred_cross(&self) -> Matrix3<f64> {
        // b̂ = m0·â + d̂.
        self.centred_aa_matrix() * self.m0.transpose() + self.centred_ad()
    }

    /// `Σ w·‖âᵢ‖²`.
    pub fn centred_aa(&self) -> f64 {
        self.centred_aa_matrix().trace()
    }

    /// `Σ w·‖b̂ᵢ‖²`.
    pub fn centred_bb(&self) -> f64 {
        let saa = self.centred_aa_matrix();
        (self.m0 * saa * self.m0.transpose()).trace()
            + 2.0 * (self.m0 * self.centred_ad()).trace()
            + self.centred_dd()
    }

    /// `Σ w·‖b̂ᵢ − m·âᵢ‖²`, the residual sum of squares of the transform with
    /// `s·R = m` and the optimal translation, together with the magnitude of
    /// the terms it is the sum of (its rounding error is about `ε` times that).
    pub fn residual_sum_of_squares(&self, m: &Matrix3<f64>) -> (f64, f64) {
        // b̂ − m·â = d̂ + Δ·â with Δ = m0 − m.
        let delta = self.m0 - m;
        let saa = self.centred_aa_matrix();
        let cross = 2.0 * (delta * self.centred_ad()).trace();
        let quad = (delta * saa * delta.transpose()).trace();
        let dd = self.centred_dd();
        let s = &self.sums;
        let raw_ad = Matrix3::from_fn(|i, j| s.ad[i][j]).norm();
        let raw_aa = s.aa[0] + s.aa[3] + s.aa[5];
        let dn = delta.norm();
        let magnitude = s.dd + 2.0 * dn * raw_ad + dn * dn * raw_aa;
        (dd + cross + quad, magnitude)
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

/// The constants of the accumulation: shifts and the prior (shifted).
struct MomentKernel {
    ca: [f64; 3],
    cb: [f64; 3],
    m: [[f64; 3]; 3],
    t: [f64; 3],
}

impl MomentKernel {
    #[inline(always)]
    fn block<A: Rows + ?Sized, B: Rows + ?Sized, W: Fn(usize) -> f64>(
        &self,
        a: &A,
        b: &B,
        lo: usize,
        hi: usize,
        weight: W,
    ) -> Sums {
        let (ca, cb, m, t) = (&self.ca, &self.cb, &self.m, &self.t);
        let mut s = Sums::default();
        for (i, (p, q)) in (lo..hi).zip(a.rows(lo, hi).zip(b.rows(lo, hi))) {
            let w = weight(i);
            let pa = [p[0] - ca[0], p[1] - ca[1], p[2] - ca[2]];
            let mut d = [0.0; 3];
            for k in 0..3 {
                d[k] =
                    (q[k] - cb[k]) - (m[k][0] * pa[0] + m[k][1] * pa[1] + m[k][2] * pa[2] + t[k]);
            }
            let wp = [w * pa[0], w * pa[1], w * pa[2]];
            s.w += w;
            for k in 0..3 {
                s.a[k] += wp[k];
                s.d[k] += w * d[k];
                for (acc, dj) in s.ad[k].iter_mut().zip(&d) {
                    *acc += wp[k] * dj;
                }
            }
            s.aa[0] += wp[0] * pa[0];
            s.aa[1] += wp[0] * pa[1];
            s.aa[2] += wp[0] * pa[2];
            s.aa[3] += wp[1] * pa[1];
            s.aa[4] += wp[1] * pa[2];
            s.aa[5] += wp[2] * pa[2];
            s.dd += w * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        }
        s
    }
}

/// Rows per structure-of-arrays block of the vectorised accumulation (the
/// scratch stays in L1).
const SOA_ROWS: usize = 256;

/// Independent accumulator lanes of the vectorised sums.
const LANES: usize = 4;

/// One block of pairs, shifted and de-interleaved: `p = a − c_a`, the prior's
/// residuals `d`, and with weights `w`, `w·p`, `w·d`. Rows past the end are 0.
struct Soa {
    p: [[f64; SOA_ROWS]; 3],
    d: [[f64; SOA_ROWS]; 3],
    w: [f64; SOA_ROWS],
    wp: [[f64; SOA_ROWS]; 3],
    wd: [[f64; SOA_ROWS]; 3],
}

/// `a·b + c`, fused where the target has FMA (elsewhere `mul_add` would be a
/// slow library call).
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// `(Σ x·y_j for each j, Σ x)` over a block, in [`LANES`] independent lanes.
///
/// On x86-64, `FMA = true` is only reached from the AVX2 + FMA variant of
/// [`MomentKernel::flat_block`] (after the CPU was checked), and uses its intrinsics.
#[inline(always)]
fn dots<const K: usize, const FMA: bool>(
    x: &[f64; SOA_ROWS],
    ys: [&[f64; SOA_ROWS]; K],
) -> ([f64; K], f64) {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        // SAFETY: see above: this CPU supports AVX2 and FMA.
        return unsafe { dots_avx2(x, ys) };
    }
    let mut acc = [[0.0; LANES]; K];
    let mut sx = [0.0; LANES];
    for base in (0..SOA_ROWS).step_by(LANES) {
        for l in 0..LANES {
            sx[l] += x[base + l];
        }
        for (a, y) in acc.iter_mut().zip(&ys) {
            for l in 0..LANES {
                a[l] = madd::<FMA>(x[base + l], y[base + l], a[l]);
            }
        }
    }
    (acc.map(|a| a.iter().sum()), sx.iter().sum())
}

/// [`dots`] with AVX2 + FMA intrinsics: one 4-lane register per sum.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn dots_avx2<const K: usize>(x: &[f64; SOA_ROWS], ys: [&[f64; SOA_ROWS]; K]) -> ([f64; K], f64) {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_setzero_pd,
        _mm256_storeu_pd,
    };
    const { assert!(SOA_ROWS % 4 == 0) };
    let mut acc: [__m256d; K] = [_mm256_setzero_pd(); K];
    let mut sx = _mm256_setzero_pd();
    for c in (0..SOA_ROWS).step_by(4) {
        // SAFETY: c + 4 <= SOA_ROWS, the length of every array.
        let xv = unsafe { _mm256_loadu_pd(x.as_ptr().add(c)) };
        sx = _mm256_add_pd(sx, xv);
        for j in 0..K {
            // SAFETY: as above.
            let yv = unsafe { _mm256_loadu_pd(ys[j].as_ptr().add(c)) };
            acc[j] = _mm256_fmadd_pd(xv, yv, acc[j]);
        }
    }
    let hsum = |v: __m256d| {
        let mut l = [0.0; 4];
        // SAFETY: `l` holds four f64.
        unsafe { _mm256_storeu_pd(l.as_mut_ptr(), v) };
        (l[0] + l[1]) + (l[2] + l[3])
    };
    (acc.map(hsum), hsum(sx))
}

impl MomentKernel {
    /// [`MomentKernel::block`] over flat row-major slices, vectorised: the CPU's
    /// widest supported variant.
    fn flat_block(&self, a: &[f64], b: &[f64], w: Option<&[f64]>, lo: usize, hi: usize) -> Sums {
        match Isa::detect() {
            // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma => unsafe { self.flat_block_avx2(a, b, w, lo, hi) },
            #[cfg(target_arch = "aarch64")]
            Isa::Neon => self.flat_sums::<true>(a, b, w, lo, hi),
            Isa::Portable => self.flat_sums::<false>(a, b, w, lo, hi),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn flat_block_avx2(
        &self,
        a: &[f64],
        b: &[f64],
        w: Option<&[f64]>,
        lo: usize,
        hi: usize,
    ) -> Sums {
        self.flat_sums::<true>(a, b, w, lo, hi)
    }

    #[inline(always)]
    fn flat_sums<const FMA: bool>(
        &self,
        a: &[f64],
        b: &[f64],
        w: Option<&[f64]>,
        lo: usize,
        hi: usize,
    ) -> Sums {
        let (ca, cb, m, t) = (&self.ca, &self.cb, &self.m, &self.t);
        let mut s = Sums::default();
        let mut soa = Soa {
            p: [[0.0; SOA_ROWS]; 3],
            d: [[0.0; SOA_ROWS]; 3],
            w: [0.0; SOA_ROWS],
            wp: [[0.0; SOA_ROWS]; 3],
            wd: [[0.0; SOA_ROWS]; 3],
        };
        let mut start = lo;
        while start < hi {
            let len = (hi - start).min(SOA_ROWS);
            let (pa, qb) = (
                &a[3 * start..3 * (start + len)],
                &b[3 * start..3 * (start + len)],
            );
            for (i, (p, q)) in pa.chunks_exact(3).zip(qb.chunks_exact(3)).enumerate() {
                let x = [p[0] - ca[0], p[1] - ca[1], p[2] - ca[2]];
                for k in 0..3 {
                    let pred = madd::<FMA>(
                        m[k][0],
                        x[0],
                        madd::<FMA>(m[k][1], x[1], madd::<FMA>(m[k][2], x[2], t[k])),
                    );
                    soa.p[k][i] = x[k];
                    soa.d[k][i] = (q[k] - cb[k]) - pred;
                }
            }
            for k in 0..3 {
                soa.p[k][len..].fill(0.0);
                soa.d[k][len..].fill(0.0);
            }
            let (wp, wd) = match w {
                Some(w) => {
                    soa.w[..len].copy_from_slice(&w[start..start + len]);
                    soa.w[len..].fill(0.0);
                    for k in 0..3 {
                        for i in 0..SOA_ROWS {
                            soa.wp[k][i] = soa.w[i] * soa.p[k][i];
                            soa.wd[k][i] = soa.w[i] * soa.d[k][i];
                        }
                    }
                    s.w += soa.w.iter().sum::<f64>();
                    (&soa.wp, &soa.wd)
                }
                None => {
                    s.w += len as f64;
                    (&soa.p, &soa.d)
                }
            };
            let (p, d) = (&soa.p, &soa.d);
            let (r0, s0) = dots::<6, FMA>(&wp[0], [&p[0], &p[1], &p[2], &d[0], &d[1], &d[2]]);
            let (r1, s1) = dots::<5, FMA>(&wp[1], [&p[1], &p[2], &d[0], &d[1], &d[2]]);
            let (r2, s2) = dots::<4, FMA>(&wp[2], [&p[2], &d[0], &d[1], &d[2]]);
            s.a[0] += s0;
            s.a[1] += s1;
            s.a[2] += s2;
            s.aa[0] += r0[0];
            s.aa[1] += r0[1];
            s.aa[2] += r0[2];
            s.aa[3] += r1[0];
            s.aa[4] += r1[1];
            s.aa[5] += r2[0];
            for j in 0..3 {
                s.ad[0][j] += r0[3 + j];
                s.ad[1][j] += r1[2 + j];
                s.ad[2][j] += r2[1 + j];
            }
            for k in 0..3 {
                let ([dd], sd) = dots::<1, FMA>(&wd[k], [&d[k]]);
                s.dd += dd;
                s.d[k] += sd;
            }
            start += len;
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums_close(x: &Sums, y: &Sums) {
        let flat = |s: &Sums| {
            let mut v = vec![s.w, s.dd];
            v.extend(s.a.iter().chain(&s.d).chain(&s.aa));
            v.extend(s.ad.iter().flatten());
            v
        };
        for (p, q) in flat(x).into_iter().zip(flat(y)) {
            assert!(
                (p - q).abs() <= 1e-12 * (1.0 + p.abs().max(q.abs())),
                "{p} vs {q}"
            );
        }
    }

    #[test]
    fn every_accumulation_path_gives_the_same_sums() {
        // 1000 rows: three full SoA blocks and a partial one.
        let n = 1000;
        let a: Vec<f64> = (0..3 * n)
            .map(|i| ((i * 7919) % 1013) as f64 * 0.01 - 5.0)
            .collect();
        let b: Vec<f64> = (0..3 * n)
            .map(|i| ((i * 104729) % 997) as f64 * 0.02 + 1.0)
            .collect();
        let w: Vec<f64> = (0..n).map(|i| (i % 5) as f64 * 0.25).collect();
        let k = MomentKernel {
            ca: [0.1, -0.2, 0.3],
            cb: [1.0, 2.0, -3.0],
            m: [[0.9, -0.1, 0.2], [0.1, 1.1, 0.0], [-0.3, 0.2, 0.8]],
            t: [0.5, -0.5, 0.25],
        };
        let (fa, fb) = (FlatRows(&a), FlatRows(&b));
        for (lo, hi) in [(0, n), (3, 700), (10, 11)] {
            let scalar = k.block(&fa, &fb, lo, hi, |_| 1.0);
            sums_close(&scalar, &k.flat_sums::<false>(&a, &b, None, lo, hi));
            sums_close(&scalar, &k.flat_block(&a, &b, None, lo, hi));
            let scalar = k.block(&fa, &fb, lo, hi, |i| w[i]);
            sums_close(&scalar, &k.flat_sums::<false>(&a, &b, Some(&w), lo, hi));
            sums_close(&scalar, &k.flat_block(&a, &b, Some(&w), lo, hi));
        }
    }
}
