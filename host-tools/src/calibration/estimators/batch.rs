//! Batch estimation on the host: `rho_p = W v_p` for many points, in f32.
//!
//! W is stored transposed (m contiguous columns of n), and each point's
//! output is accumulated as `out = 0; out += W[:, i] * v_i` for i = 0..m.
//! Per output element that is exactly the library kernel's sequence
//! (`acc = 0; acc += w_ji * v_i`, i ascending, unfused), so the results are
//! bit-identical to `brdf_meter::kernel::mat_vec_f32_slice` (tested) and to the
//! device, while the inner loop runs over n contiguous outputs and
//! vectorises.
//!
//! [`BatchEstimator::estimate_par_into`] spreads a large batch over the
//! current rayon pool in blocks of [`PAR_BLOCK_POINTS`] points; each point is
//! still computed by the same code, so the results do not depend on the
//! thread count (tested).
use super::LinearEstimator;
use rayon::prelude::*;

/// Points per rayon task: 4096 points of n = 81 outputs are 1.3 MB written,
/// so scheduling is noise against the work, and a multiple of 8 points keeps
/// every block's output 32-byte aligned when the batch's is (the streamed
/// path then needs no scalar lead-in per block).
pub const PAR_BLOCK_POINTS: usize = 4096;

/// Output bins computed together in registers.
const LANES: usize = 16;
/// Points computed together on the AVX2 path (8 accumulator chains), and per
/// streamed block (8 points of n floats are a whole number of 32-byte vectors).
#[cfg(target_arch = "x86_64")]
const GROUP: usize = 8;
/// Below this many points the output stays in cache: plain stores.
#[cfg(target_arch = "x86_64")]
const STREAM_MIN_POINTS: usize = 4096;
/// Largest n of the streamed path (its staging buffer is on the stack).
#[cfg(target_arch = "x86_64")]
const STREAM_MAX_N: usize = 256;

#[cfg(target_arch = "x86_64")]
#[repr(align(32))]
struct Aligned([f32; GROUP * STREAM_MAX_N]);

/// An f32 estimator laid out for batches.
#[derive(Clone, Debug)]
pub struct BatchEstimator {
    n: usize,
    m: usize,
    /// n rounded up to a multiple of `LANES`.
    n_pad: usize,
    /// `wt[i * n_pad + j] = W[j][i]`, zero in the padding.
    wt: Vec<f32>,
}

impl BatchEstimator {
    /// From W row-major n x m (the blob and kernel layout).
    ///
    /// # Panics
    /// If `w.len() != n * m`.
    pub fn from_row_major(w: &[f32], n: usize, m: usize) -> Self {
        assert_eq!(w.len(), n * m, "W must be n x m row-major");
        let n_pad = n.div_ceil(LANES) * LANES;
        let mut wt = vec![0.0f32; n_pad * m];
        for j in 0..n {
            for i in 0..m {
                wt[i * n_pad + j] = w[j * m + i];
            }
        }
        Self { n, m, n_pad, wt }
    }

    /// From a trained estimator (rounded to f32).
    pub fn from_estimator(e: &LinearEstimator) -> Self {
        Self::from_row_major(&e.w_f32_row_major(), e.n(), e.m())
    }

    /// Bins n.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Readings m.
    pub fn m(&self) -> usize {
        self.m
    }

    /// Estimates `readings.len() / m` points: `readings` is points x m
    /// (row-major), `out` points x n.
    ///
    /// Blocks of `LANES` outputs are accumulated in registers over the m
    /// readings (`acc = 0; acc += w * v_i`, i ascending) and stored once.
    ///
    /// # Panics
    /// If the lengths do not agree.
    pub fn estimate_into(&self, readings: &[f32], out: &mut [f32]) {
        let m = self.m;
        assert!(m > 0 && readings.len().is_multiple_of(m), "readings must be points x m");
        let points = readings.len() / m;
        assert_eq!(out.len(), points * self.n, "out must be points x n");
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above). AVX2 only
            // widens the vectors; FMA is not enabled, so each element's
            // arithmetic (unfused multiply, then add) is unchanged.
            unsafe { self.run_avx2(readings, out) };
            return;
        }
        self.run(readings, out);
    }

    /// [`Self::estimate_into`] on every thread of the current rayon pool
    /// (the global one, or the pool whose `install` this runs in): blocks of
    /// [`PAR_BLOCK_POINTS`] points, each estimated exactly as alone. Batches
    /// of at most one block stay on the calling thread.
    ///
    /// # Panics
    /// If the lengths do not agree.
    pub fn estimate_par_into(&self, readings: &[f32], out: &mut [f32]) {
        let (n, m) = (self.n, self.m);
        assert!(m > 0 && readings.len().is_multiple_of(m), "readings must be points x m");
        assert_eq!(out.len(), readings.len() / m * n, "out must be points x n");
        if readings.len() / m <= PAR_BLOCK_POINTS || rayon::current_num_threads() == 1 {
            self.estimate_into(readings, out);
            return;
        }
        readings
            .par_chunks(PAR_BLOCK_POINTS * m)
            .zip(out.par_chunks_mut(PAR_BLOCK_POINTS * n))
            .for_each(|(r, o)| self.estimate_into(r, o));
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2(&self, readings: &[f32], out: &mut [f32]) {
        use std::arch::x86_64::*;
        let (n, m, np) = (self.n, self.m, self.n_pad);
        let points = readings.len() / m;
        if n > STREAM_MAX_N {
            self.run(readings, out);
            return;
        }
        // Large batches are bound by writing the output: stream it past the
        // caches (non-temporal stores need no read-for-ownership, halving
        // the memory traffic) once the output is 32-byte aligned.
        let mut lead = 0;
        let stream = points >= STREAM_MIN_POINTS && {
            while lead < GROUP && !(out.as_ptr() as usize + 4 * n * lead).is_multiple_of(32) {
                lead += 1;
            }
            lead < GROUP
        };
        if !stream {
            lead = 0;
        }
        self.run(&readings[..lead * m], &mut out[..lead * n]);
        let groups = (points - lead) / GROUP;
        let mut packed = Aligned([0.0f32; GROUP * STREAM_MAX_N]);
        let wt = self.wt.as_ptr();
        let full = n / 8;
        let rest = n - full * 8;
        // Lanes < rest are written by the last, partial block.
        let mask = _mm256_setr_epi32(
            if rest > 0 { -1 } else { 0 },
            if rest > 1 { -1 } else { 0 },
            if rest > 2 { -1 } else { 0 },
            if rest > 3 { -1 } else { 0 },
            if rest > 4 { -1 } else { 0 },
            if rest > 5 { -1 } else { 0 },
            if rest > 6 { -1 } else { 0 },
            0,
        );
        for g in 0..groups {
            let p0 = lead + g * GROUP;
            let v = readings[p0 * m..(p0 + GROUP) * m].as_ptr();
            // Where this group's GROUP x n results go: straight to `out`, or
            // packed in L1 first when they are then streamed.
            let dst: *mut f32 = if stream { packed.0.as_mut_ptr() } else { out[p0 * n..(p0 + GROUP) * n].as_mut_ptr() };
            // 4 points x 16 bins per step (8 accumulator chains): each load
            // of W serves 4 points and each broadcast reading 2 vectors of
            // bins. Per bin: acc = 0; acc += w_i * v_i, i ascending,
            // multiply then add (no FMA): the kernel's arithmetic.
            let nb = n.div_ceil(8);
            for half in 0..GROUP / 4 {
                let vh = v.wrapping_add(half * 4 * m);
                let dh = dst.wrapping_add(half * 4 * n);
                let mut b = 0;
                while b < nb {
                    let two = b + 1 < nb;
                    let mut a = [[_mm256_setzero_ps(); 2]; 4];
                    for i in 0..m {
                        // SAFETY: i * np + b * 8 + 16 <= m * np = wt.len() when
                        // `two` (np is a multiple of 16 >= nb * 8); p * m + i < 4 * m.
                        let w0 = unsafe { _mm256_loadu_ps(wt.add(i * np + b * 8)) };
                        let w1 = if two { unsafe { _mm256_loadu_ps(wt.add(i * np + b * 8 + 8)) } } else { w0 };
                        for (p, ap) in a.iter_mut().enumerate() {
                            let x = unsafe { _mm256_broadcast_ss(&*vh.add(p * m + i)) };
                            ap[0] = _mm256_add_ps(ap[0], _mm256_mul_ps(w0, x));
                            ap[1] = _mm256_add_ps(ap[1], _mm256_mul_ps(w1, x));
                        }
                    }
                    for (p, ap) in a.iter().enumerate() {
                        for (k, acc) in ap.iter().enumerate().take(if two { 2 } else { 1 }) {
                            let bb = b + k;
                            // SAFETY: `dst` holds GROUP * n floats; a full block
                            // ends at p * n + bb * 8 + 8 <= p * n + n, the partial
                            // one writes only its `rest` lanes.
                            unsafe {
                                if bb < full {
                                    _mm256_storeu_ps(dh.add(p * n + bb * 8), *acc);
                                } else {
                                    _mm256_maskstore_ps(dh.add(p * n + bb * 8), mask, *acc);
                                }
                            }
                        }
                    }
                    b += 2;
                }
            }
            if stream {
                let o = out[p0 * n..(p0 + GROUP) * n].as_mut_ptr();
                // GROUP = 8 points of n floats: n whole 8-float vectors.
                for k in 0..n {
                    // SAFETY: `o` is 32-byte aligned (lead chosen so; each
                    // group is 32 n bytes) and holds GROUP * n floats.
                    unsafe { _mm256_stream_ps(o.add(k * 8), _mm256_load_ps(packed.0.as_ptr().add(k * 8))) };
                }
            }
        }
        if stream {
            // Orders the streaming stores before anything that follows.
            _mm_sfence();
        }
        let done = lead + groups * GROUP;
        self.run(&readings[done * m..], &mut out[done * n..]);
    }

    #[inline(always)]
    fn run(&self, readings: &[f32], out: &mut [f32]) {
        let (n, m, np) = (self.n, self.m, self.n_pad);
        let full = n / LANES;
        for (v, o) in readings.chunks_exact(m).zip(out.chunks_exact_mut(n)) {
            // Full blocks: fixed-size stores, no call in the loop, so the
            // out-of-order core overlaps the blocks' dependency chains.
            for b in 0..full {
                let acc = self.block(v, b * LANES, np);
                o[b * LANES..(b + 1) * LANES].copy_from_slice(&acc);
            }
            if full * LANES < n {
                let acc = self.block(v, full * LANES, np);
                for (dst, src) in o[full * LANES..].iter_mut().zip(acc.iter()) {
                    *dst = *src;
                }
            }
        }
    }

    /// Outputs `j0..j0 + LANES` of one point: `acc = 0; acc += W[j][i] * v_i`, i ascending.
    #[inline(always)]
    fn block(&self, v: &[f32], j0: usize, np: usize) -> [f32; LANES] {
        let mut acc = [0.0f32; LANES];
        for (i, &vi) in v.iter().enumerate() {
            let col: &[f32; LANES] = self.wt[i * np + j0..i * np + j0 + LANES].try_into().expect("padded");
            for l in 0..LANES {
                acc[l] += col[l] * vi;
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn streamed_large_batches_are_bit_identical_at_any_output_alignment() {
        let (n, m, p) = (81, 7, 5000);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
        let v: Vec<f32> = (0..p * m).map(|_| rng.random_range(0.0f32..300.0)).collect();
        let b = BatchEstimator::from_row_major(&w, n, m);
        let mut one = vec![0.0f32; n];
        for shift in 0..8 {
            let mut buf = vec![f32::NAN; p * n + 8];
            b.estimate_into(&v, &mut buf[shift..shift + p * n]);
            for k in (0..p).step_by(7).chain(p - 9..p) {
                brdf_meter::kernel::mat_vec_f32_slice(&w, &v[k * m..(k + 1) * m], &mut one);
                for j in 0..n {
                    assert_eq!(buf[shift + k * n + j].to_bits(), one[j].to_bits(), "shift {shift} point {k} bin {j}");
                }
            }
            assert!(buf[shift..shift + p * n].iter().all(|x| !x.is_nan()), "shift {shift}: a point was not written");
        }
    }

    #[test]
    fn parallel_batches_are_bit_identical_at_every_thread_count() {
        // Not a whole number of blocks, so the last block is partial.
        let (n, m, p) = (81, 7, 3 * PAR_BLOCK_POINTS + 1234);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
        let v: Vec<f32> = (0..p * m).map(|_| rng.random_range(0.0f32..300.0)).collect();
        let b = BatchEstimator::from_row_major(&w, n, m);
        let mut one = vec![0.0f32; n];
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            for shift in [0, 3] {
                let mut buf = vec![f32::NAN; p * n + 8];
                pool.install(|| b.estimate_par_into(&v, &mut buf[shift..shift + p * n]));
                for k in 0..p {
                    brdf_meter::kernel::mat_vec_f32_slice(&w, &v[k * m..(k + 1) * m], &mut one);
                    for j in 0..n {
                        assert_eq!(
                            buf[shift + k * n + j].to_bits(),
                            one[j].to_bits(),
                            "{threads} threads, shift {shift}: point {k} bin {j}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn bit_identical_to_the_device_kernel() {
        for (n, m, p) in [(81, 7, 300), (16, 3, 20), (3, 1, 5), (33, 9, 10)] {
            let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
            let w: Vec<f32> = (0..n * m).map(|_| rng.random_range(-50.0f32..50.0)).collect();
            let v: Vec<f32> = (0..p * m).map(|_| rng.random_range(-1.0f32..300.0)).collect();
            let b = BatchEstimator::from_row_major(&w, n, m);
            let mut out = vec![0.0f32; p * n];
            b.estimate_into(&v, &mut out);
            let mut one = vec![0.0f32; n];
            for k in 0..p {
                brdf_meter::kernel::mat_vec_f32_slice(&w, &v[k * m..(k + 1) * m], &mut one);
                for j in 0..n {
                    assert_eq!(out[k * n + j].to_bits(), one[j].to_bits(), "n={n} m={m} point {k} bin {j}");
                }
            }
        }
    }
}
