//! Which calibration reads which surface: a surface that is also one of the
//! calibration's training samples (a prior sample, or one of the gloss
//! standards its gloss rows are fitted with) is read only by calibrations
//! trained without it; every other surface by the calibration trained on
//! everything, the one `train` writes.
//!
//! A surface is recognised as a training sample by its grid vector (the
//! prior's own representation: the same model gives the same vector bit
//! for bit), so this needs no naming convention and catches a test set
//! passed as the prior under another name. The surfaces of each family
//! that are training samples are split into K folds (seeded shuffle); fold
//! f's calibration is trained on the pairs of every other sample, all
//! families' fold-f members left out together (K trainings serve every
//! family). Leaving them out of the sample pairs is leaving them out of the
//! prior: `Pairs::of_samples` renormalises the remaining weights.
use crate::calibration::train::ZonePairs;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// The relative difference below which two grid vectors are one sample.
const SAME_SAMPLE: f64 = 1e-9;

/// The training samples (columns of `samples`) that are the surface `v`.
pub fn matching(v: &DVector<f64>, samples: &DMatrix<f64>) -> Vec<usize> {
    let scale = v.amax().max(f64::MIN_POSITIVE);
    (0..samples.ncols())
        .filter(|&k| {
            let c = samples.column(k);
            c.len() == v.len() && (c - v).amax() <= SAME_SAMPLE * scale.max(c.amax())
        })
        .collect()
}

/// The prior sample (a column of `samples`, none of `left_out`) nearest
/// the binned BRDF `rho` whose peak is `peak`, and how far: the RMS over
/// the bins of their difference over the peak, the BRDF error's own unit,
/// so an estimator that took the surface for that sample would read it
/// that well. `None` when no sample is left or the peak is not above 0.
pub fn nearest(rho: &DVector<f64>, peak: f64, samples: &DMatrix<f64>, left_out: &[usize]) -> Option<(usize, f64)> {
    let scale = peak * (rho.len() as f64).sqrt();
    if scale.is_nan() || scale <= 0.0 || samples.nrows() != rho.len() {
        return None;
    }
    (0..samples.ncols())
        .filter(|k| !left_out.contains(k))
        .map(|k| (k, (samples.column(k) - rho).norm() / scale))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// One calibration to train: the training samples it leaves out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeldOut {
    /// Fold (`None`: the calibration on everything).
    pub fold: Option<usize>,
    /// Prior samples left out (indices into the prior).
    pub prior: Vec<usize>,
    /// Gloss standards left out (indices into `gloss_rows::standards`).
    pub standards: Vec<usize>,
}

impl HeldOut {
    /// The sample pairs of `all` without the left-out samples.
    pub fn pairs(&self, all: &ZonePairs) -> ZonePairs {
        ZonePairs {
            prior: all.prior.iter().map(|p| p.of_samples(|s| !self.prior.contains(&s))).collect(),
            standards: all.standards.iter().map(|p| p.of_samples(|s| !self.standards.contains(&s))).collect(),
        }
    }

    /// What the calibration is, for the progress line.
    pub fn label(&self, folds: usize) -> String {
        match self.fold {
            Some(f) => format!(
                "fold {}/{folds}: without {} prior sample(s), {} standard(s)",
                f + 1,
                self.prior.len(),
                self.standards.len()
            ),
            None => "on the whole prior".into(),
        }
    }
}

/// Where one surface is among the training samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Membership {
    /// Prior samples that are this surface.
    pub prior: Vec<usize>,
    /// Gloss standards that are this surface (the black glass left out).
    pub standards: Vec<usize>,
    /// Whether it is the gloss scale's reference (the black glass): in
    /// every calibration, never left out.
    pub reference: bool,
}

impl Membership {
    /// Whether the surface is a training sample at all.
    pub fn in_training(&self) -> bool {
        !self.prior.is_empty() || !self.standards.is_empty()
    }
}

/// The plan: the calibrations, and per family and surface the one that reads it.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Calibrations to train; the last is the one on everything when any
    /// surface needs it.
    pub calibrations: Vec<HeldOut>,
    /// Per family, per surface: index into `calibrations`.
    pub reader: Vec<Vec<usize>>,
    /// Folds K (0 when no surface is a training sample).
    pub folds: usize,
}

/// Plans the calibrations for `families` (per family, per surface, its
/// membership): K = `folds` (at least 2, at most the largest family's
/// members) when any surface is a training sample.
pub fn plan(families: &[Vec<Membership>], folds: usize, seed: u64) -> Plan {
    let largest = families.iter().map(|f| f.iter().filter(|m| m.in_training()).count()).max().unwrap_or(0);
    let k = if largest == 0 { 0 } else { folds.clamp(2, largest.max(2)) };
    let mut calibrations: Vec<HeldOut> = (0..k).map(|f| HeldOut { fold: Some(f), ..Default::default() }).collect();
    let mut reader = Vec::with_capacity(families.len());
    let mut needs_full = false;
    for (fi, fam) in families.iter().enumerate() {
        let mut members: Vec<usize> = (0..fam.len()).filter(|&i| fam[i].in_training()).collect();
        members.shuffle(&mut ChaCha8Rng::seed_from_u64(seed ^ (0x5EED_F01D + fi as u64)));
        let mut row = vec![usize::MAX; fam.len()];
        for (pos, &i) in members.iter().enumerate() {
            let f = pos % k;
            row[i] = f;
            calibrations[f].prior.extend(&fam[i].prior);
            calibrations[f].standards.extend(&fam[i].standards);
        }
        needs_full |= row.contains(&usize::MAX);
        reader.push(row);
    }
    // Folds no surface fell into train nothing.
    let used: Vec<usize> = (0..k).filter(|f| reader.iter().flatten().any(|r| r == f)).collect();
    let renumber = |r: usize| used.iter().position(|u| *u == r);
    let mut calibrations: Vec<HeldOut> = used.iter().map(|&f| std::mem::take(&mut calibrations[f])).collect();
    for c in &mut calibrations {
        c.prior.sort_unstable();
        c.prior.dedup();
        c.standards.sort_unstable();
        c.standards.dedup();
    }
    let full = calibrations.len();
    if needs_full {
        calibrations.push(HeldOut::default());
    }
    let reader = reader.into_iter().map(|row| row.into_iter().map(|r| renumber(r).unwrap_or(full)).collect()).collect();
    Plan { calibrations, reader, folds: k }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_sample_is_the_closest_one_not_left_out_in_the_errors_unit() {
        // Three samples on four bins; the surface peaks at 2.
        let samples = DMatrix::from_column_slice(4, 3, &[1.0, 2.0, 1.0, 0.0, 1.0, 2.0, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0]);
        let rho = DVector::from_column_slice(&[1.0, 2.0, 1.0, 0.0]);
        assert_eq!(nearest(&rho, 2.0, &samples, &[]), Some((0, 0.0)));
        // Left out, the surface's twin is passed over: the second sample
        // differs by 0.5 in one bin, RMS 0.25, over the peak 0.125.
        let (k, d) = nearest(&rho, 2.0, &samples, &[0]).unwrap();
        assert_eq!(k, 1);
        assert!((d - 0.125).abs() < 1e-12, "{d}");
        // Nothing left, a surface without a peak, or another grid: none.
        assert_eq!(nearest(&rho, 2.0, &samples, &[0, 1, 2]), None);
        assert_eq!(nearest(&rho, 0.0, &samples, &[]), None);
        assert_eq!(nearest(&DVector::zeros(3), 1.0, &samples, &[]), None);
    }

    #[test]
    fn members_are_read_only_by_folds_that_left_them_out() {
        let m = |p: &[usize], s: &[usize]| Membership { prior: p.to_vec(), standards: s.to_vec(), reference: false };
        // Family 0: 5 surfaces, 4 in the prior; family 1: 3 standards and one new surface.
        let fams = vec![
            vec![m(&[0], &[]), m(&[1], &[]), m(&[], &[]), m(&[2], &[]), m(&[3], &[])],
            vec![m(&[], &[0]), m(&[], &[1]), m(&[], &[2]), m(&[], &[])],
        ];
        let p = plan(&fams, 3, 7);
        assert_eq!(p.folds, 3);
        assert_eq!(p.calibrations.len(), 4);
        assert_eq!(p.calibrations[3], HeldOut::default());
        for (fam, row) in fams.iter().zip(&p.reader) {
            for (mem, &r) in fam.iter().zip(row) {
                let c = &p.calibrations[r];
                if mem.in_training() {
                    assert!(c.fold.is_some());
                    assert!(mem.prior.iter().all(|s| c.prior.contains(s)));
                    assert!(mem.standards.iter().all(|s| c.standards.contains(s)));
                } else {
                    assert_eq!(r, 3);
                }
            }
        }
        // Nothing in training: one calibration, no folds.
        let p = plan(&[vec![m(&[], &[]); 3]], 5, 1);
        assert_eq!((p.folds, p.calibrations.len()), (0, 1));
        let v = DVector::from_vec(vec![1.0, 2.0]);
        let s = DMatrix::from_columns(&[DVector::from_vec(vec![1.0, 2.5]), v.clone()]);
        assert_eq!(matching(&v, &s), vec![1]);
    }
}
