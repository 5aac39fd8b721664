//! The machine's memory bandwidth, measured the way STREAM does, so the host
//! batch kernel can be compared with the fastest it could possibly run.
//!
//! Two kernels over f32 arrays far larger than any cache, split into one
//! contiguous block per thread of the current rayon pool (STREAM's static
//! OpenMP schedule):
//! - copy, `c = a` (`copy_from_slice`, i.e. the C library's `memcpy`, which
//!   streams large copies past the caches): 8 bytes per element;
//! - triad, `a = b + s c`: 12 bytes per element.
//!
//! Bytes are counted as STREAM counts them (what the kernel names, not the
//! read-for-ownership traffic plain stores add), best of `runs` runs after a
//! warm-up pass that also faults every page in.
use crate::evaluation::timing::best_and_median;
use rayon::prelude::*;
use serde::Serialize;
use std::hint::black_box;

/// Bandwidth at one thread count, bytes per second.
#[derive(Clone, Debug, Serialize)]
pub struct Bandwidth {
    /// Threads of the pool that ran it.
    pub threads: usize,
    /// Copy, best run.
    pub copy_bytes_per_s: f64,
    /// Triad, best run.
    pub triad_bytes_per_s: f64,
}

impl Bandwidth {
    /// The larger of the two: the bandwidth the floor is taken at (the
    /// harder target for the batch kernel).
    pub fn best_bytes_per_s(&self) -> f64 {
        self.copy_bytes_per_s.max(self.triad_bytes_per_s)
    }
}

/// The three arrays, allocated and touched once and reused for every thread
/// count.
pub struct Arrays {
    a: Vec<f32>,
    b: Vec<f32>,
    c: Vec<f32>,
}

impl Arrays {
    /// Three arrays of `len` f32 (STREAM wants each at least 4x the last
    /// level cache).
    pub fn new(len: usize) -> Self {
        Self { a: vec![1.0; len], b: vec![2.0; len], c: vec![0.5; len] }
    }

    /// Copy and triad on the current rayon pool, best of `runs`.
    pub fn measure(&mut self, runs: usize) -> Bandwidth {
        let threads = rayon::current_num_threads();
        let len = self.a.len();
        let block = len.div_ceil(threads).max(1);
        let (a, b, c) = (&mut self.a, &mut self.b, &mut self.c);
        let copy = |a: &[f32], c: &mut [f32]| {
            c.par_chunks_mut(block).zip(a.par_chunks(block)).for_each(|(c, a)| c.copy_from_slice(a));
        };
        let triad = |a: &mut [f32], b: &[f32], c: &[f32]| {
            let s = black_box(3.0f32);
            a.par_chunks_mut(block).zip(b.par_chunks(block)).zip(c.par_chunks(block)).for_each(|((a, b), c)| {
                for ((a, &b), &c) in a.iter_mut().zip(b).zip(c) {
                    *a = b + s * c;
                }
            });
        };
        let (copy_s, _) = best_and_median(runs, || copy(black_box(a), black_box(c)));
        let (triad_s, _) = best_and_median(runs, || triad(black_box(a), black_box(b), black_box(c)));
        black_box((&a, &c));
        let bytes = (len * std::mem::size_of::<f32>()) as f64;
        Bandwidth { threads, copy_bytes_per_s: 2.0 * bytes / copy_s, triad_bytes_per_s: 3.0 * bytes / triad_s }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copy_and_triad_compute_what_they_count() {
        let mut arr = Arrays::new(10_001);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().expect("pool");
        let bw = pool.install(|| arr.measure(2));
        assert_eq!(bw.threads, 3);
        assert!(bw.copy_bytes_per_s.is_finite() && bw.copy_bytes_per_s > 0.0);
        assert!(bw.triad_bytes_per_s.is_finite() && bw.triad_bytes_per_s > 0.0);
        // copy made c = a = 1; the triad then a = b + 3 c = 2 + 3 = 5, everywhere.
        assert!(arr.c.iter().all(|&x| x == 1.0));
        assert!(arr.a.iter().all(|&x| x == 5.0));
    }
}
