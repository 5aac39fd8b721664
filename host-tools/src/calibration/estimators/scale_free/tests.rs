use super::band::{band_quantile, covering_unit};
use super::cross_validation::{folds, noisy};
use super::*;
use crate::forward::grid::AngleGrid;
use crate::forward::optics::{Instrument, system_matrix};
use crate::forward::prior::SampleSet;

fn setup() -> (DMatrix<f64>, WeightedSamples) {
    let grid = AngleGrid::patent();
    let inst = Instrument::patent_profile();
    let h = system_matrix(&inst, &grid, false).unwrap();
    let rho_d: Vec<f64> = (0..6).map(|i| 0.05 + 0.15 * i as f64).collect();
    let alpha: Vec<f64> = (0..6).map(|i| 0.03 + 0.02 * i as f64).collect();
    let set = SampleSet::ward_grid(&rho_d, &alpha);
    // Scale the samples over orders of magnitude, as real materials are.
    let mut s = set.on_grid(&grid, inst.view_deg);
    for (c, mut col) in s.column_iter_mut().enumerate() {
        col *= 10f64.powi(c as i32 % 4 - 1);
    }
    (h, WeightedSamples::equal(s))
}

#[test]
fn the_covering_unit_uncertainty_states_exactly_the_error() {
    for (est, e, s) in [(0.5, 0.1, 2.0), (30.0, 12.0, 0.7), (0.0, 0.3, 1.0), (1e-6, 1e-3, 5.0)] {
        let unit = covering_unit(est, e, s);
        let stated = f64::from(root_uncertainty(unit as f32, est as f32, s as f32));
        assert!((COVERAGE_K * stated - e).abs() <= 1e-5 * e, "est {est} e {e} s {s}: {stated}");
    }
    assert_eq!(covering_unit(2.0, 0.0, 1.0), 0.0);
}

#[test]
fn the_weighted_quantile_counts_weights_not_values() {
    let mut xs = vec![(3.0, 1.0), (1.0, 1.0), (2.0, 2.0)];
    // Sorted 1 (w 1), 2 (w 2), 3 (w 1): a quarter of the weight is at 1,
    // three quarters at or below 2.
    assert_eq!(weighted_quantile(&mut xs, 0.25), 1.0);
    assert_eq!(weighted_quantile(&mut xs, 0.5), 2.0);
    assert_eq!(weighted_quantile(&mut xs, 0.75), 2.0);
    assert_eq!(weighted_quantile(&mut xs, 0.95), 3.0);
    assert_eq!(weighted_quantile(&mut [], 0.5), f64::MAX);
}

#[test]
fn a_bins_band_covers_the_materials_and_their_variants_each_on_its_own() {
    // 100 materials' covering units 1..=100 and 100 variants', the two
    // families of equal weight (a material's variants share half of it).
    let materials: Vec<(f64, f64)> = (1..=100).map(|i| (f64::from(i), 1.0)).collect();
    let easy: Vec<(f64, f64)> = (1..=100).map(|i| (0.01 * f64::from(i), 1.0)).collect();
    let hard: Vec<(f64, f64)> = (1..=100).map(|i| (10.0 * f64::from(i), 1.0)).collect();
    // Pooled, easy variants narrow the band to cover 90 % of the
    // materials, and hard ones are covered at 900 where 95 % of them
    // need 950.
    let pooled = |v: &[(f64, f64)]| weighted_quantile(&mut [materials.clone(), v.to_vec()].concat(), COVERAGE);
    assert_eq!((pooled(&easy), pooled(&hard)), (90.0, 900.0));
    assert_eq!(band_quantile(&[materials.clone(), easy]), Some(95.0), "easy variants do not narrow it");
    assert_eq!(band_quantile(&[materials.clone(), hard]), Some(950.0), "hard variants are covered too");
    // A family too small to set its own (its 95th percentile: 37,000)
    // only counts in the pool (33,000: the 33rd of its 39 completes 95 %
    // of the 139 readings' weight).
    let few: Vec<(f64, f64)> = (1..=39).map(|i| (1e3 * f64::from(i), 1.0)).collect();
    assert_eq!(band_quantile(&[materials.clone(), few]), Some(33_000.0));
    assert_eq!(band_quantile(&[Vec::new(), Vec::new()]), None);
}

#[test]
fn the_uncertaintys_folds_hold_out_each_kind_of_material_whole() {
    let (h, prior) = setup();
    let k = prior.samples.ncols();
    // Every sample twice, the copy eight times brighter: one shape.
    let samples = DMatrix::from_fn(prior.samples.nrows(), 2 * k, |j, c| {
        prior.samples[(j, c % k)] * if c < k { 1.0 } else { 8.0 }
    });
    let noise = ReadingNoise::relative(0.02, h.nrows());
    let pairs = Pairs::in_plane(&h, &samples, &vec![1.0 / (2 * k) as f64; 2 * k], &noise);
    let nz = normalise_truth(&pairs, &ScaleFreeOptions::default()).unwrap();
    let fold = shape_folds(&pairs, &nz, 7);
    let nf = fold.iter().max().unwrap() + 1;
    assert!((2..=FOLDS).contains(&nf), "{fold:?}");
    assert!((0..nf).all(|f| fold.contains(&f)), "no fold empty: {fold:?}");
    for c in 0..k {
        assert_eq!(fold[c], fold[c + k], "sample {c} and its brighter copy: {fold:?}");
    }
    // Random folds split most such pairs, so the copy would be in
    // training when its twin is held out.
    let random = folds(&pairs, 7);
    assert!((0..k).filter(|c| random[*c] != random[c + k]).count() > k / 2, "{random:?}");
    // Too few samples to group: the random folds.
    let few = Pairs::in_plane(&h, &samples.columns(0, 6).into_owned(), &[1.0 / 6.0; 6], &noise);
    let nz_few = normalise_truth(&few, &ScaleFreeOptions::default()).unwrap();
    assert_eq!(shape_folds(&few, &nz_few, 7), folds(&few, 7));
}

#[test]
fn host_f64_and_device_f32_agree_and_scaled_copies_scale() {
    let (h, prior) = setup();
    let z = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
    for k in [0, 7, 20] {
        let v = &h * prior.samples.column(k);
        let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
        let (est, sigma, _, _) = z.estimate_f32(&v32);
        let e64 = z.maps[0].estimate(&v.map(|x| x as f32 as f64), false);
        let scale = e64.amax();
        for j in 0..est.len() {
            assert!((est[j] as f64 - e64[j]).abs() <= 1e-4 * scale, "{k} {j}");
        }
        // A scaled copy: the estimate and its uncertainty scale with it, bit for bit for 2^3.
        let v8: Vec<f32> = v32.iter().map(|x| x * 8.0).collect();
        let (est8, sigma8, stat8, _) = z.estimate_f32(&v8);
        for j in 0..est.len() {
            assert_eq!(est8[j], est[j] * 8.0);
            assert_eq!(sigma8[j], sigma[j] * 8.0);
        }
        assert_eq!(stat8, z.out_of_prior.stat(&v32));
        // Close to the truth (the prior's own sample, noise-free).
        let truth = prior.samples.column(k).into_owned();
        let e = peak_error(&DVector::from_iterator(est.len(), est.iter().map(|x| *x as f64)), &truth);
        assert!(e < 0.1, "sample {k}: peak-normalised error {e}");
    }
}

#[test]
fn flag_rate_on_the_priors_own_samples_and_far_materials() {
    let (h, prior) = setup();
    let z = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let (mut flagged, mut total) = (0, 0);
    for k in 0..prior.samples.ncols() {
        for _ in 0..5 {
            let v0 = &h * prior.samples.column(k);
            let v = noisy(&v0, &v0.map(|x| (0.02 * x).powi(2)), &mut rng);
            let v32: Vec<f32> = v.iter().map(|x| *x as f32).collect();
            flagged += usize::from(z.out_of_prior.stat(&v32) > z.out_of_prior.threshold);
            total += 1;
        }
    }
    // The threshold was set for 5 % on held-out samples; the prior's own
    // samples (seen in training) are flagged at most that often.
    assert!((flagged as f64) <= 0.05 * total as f64 + 1.0, "{flagged} of {total}");
    // A material unlike any Ward sample: light only from one LED.
    let mut v = vec![1e-4f32; h.nrows()];
    v[0] = 1.0;
    assert!(z.out_of_prior.stat(&v) > z.out_of_prior.threshold);
}

#[test]
fn the_cluster_count_is_the_most_accurate_that_reads_kinds_held_out_no_worse_than_two() {
    let (h, prior) = setup();
    let noise = ReadingNoise::relative(0.02, h.nrows());
    let pairs = Pairs::in_plane(&h, &prior.samples, &prior.weights, &noise);
    let opts = ScaleFreeOptions { piecewise: true, ..Default::default() };
    let scored = score_counts(&pairs, &opts, &CLUSTER_COUNTS).unwrap();
    let (random, kinds): (Vec<f64>, Vec<f64>) = scored.iter().map(|s| (s.random, s.kinds)).unzip();
    for (k, (r, kind)) in CLUSTER_COUNTS.iter().zip(random.iter().zip(&kinds)) {
        // A kind held out whole has no near twin left in training.
        assert!(kind > r, "{k} clusters: kinds held out {kind}, random folds {r}");
    }
    let z = train_pairs(&pairs, &opts).unwrap();
    let c = guarded_count(std::slice::from_ref(&scored));
    assert_eq!(z.maps.len(), CLUSTER_COUNTS[c]);
    assert!(kinds[c] <= kinds[0]);
    for (i, (r, k)) in random.iter().zip(&kinds).enumerate() {
        assert!(
            *k > kinds[0] || *r >= random[c],
            "{} clusters would have been taken: {random:?} {kinds:?}",
            CLUSTER_COUNTS[i]
        );
    }
}

#[test]
fn the_guarded_count_sums_the_zones_and_drops_counts_that_read_kinds_held_out_worse() {
    // Random folds prefer the most clusters; kinds held out say the
    // last count extrapolates worse than the first: the middle one.
    let zones = |random: &[&[f64]], kinds: &[&[f64]]| -> Vec<Vec<CountScore>> {
        random
            .iter()
            .zip(kinds)
            .map(|(r, k)| r.iter().zip(*k).map(|(r, k)| CountScore { ridge: 1e-8, random: *r, kinds: *k }).collect())
            .collect()
    };
    let random: [&[f64]; 2] = [&[0.05, 0.04, 0.03], &[0.05, 0.04, 0.03]];
    assert_eq!(guarded_count(&zones(&random, &[&[0.25, 0.125, 0.5], &[0.25, 0.25, 0.25]])), 1);
    // Summed over the zones, the last one reads kinds as well as the first.
    assert_eq!(guarded_count(&zones(&random, &[&[0.25, 0.25, 0.5], &[0.25, 0.25, 0.0]])), 2);
    // Nothing better on random folds than the fewest: the fewest.
    assert_eq!(guarded_count(&zones(&[&[0.02, 0.04]], &[&[0.3, 0.1]])), 0);
    assert_eq!(guarded_count(&[]), 0);
}

#[test]
fn with_a_grid_broad_and_sharp_estimates_each_take_their_own_band() {
    // Ward lobes from near-mirrors (alpha 0.005) to broad ones, scaled
    // over orders of magnitude as in `setup`.
    let (grid, inst) = (AngleGrid::patent(), Instrument::patent_profile());
    let h = system_matrix(&inst, &grid, false).unwrap();
    let rho_d: Vec<f64> = (0..6).map(|i| 0.05 + 0.15 * i as f64).collect();
    let alpha = [0.005, 0.01, 0.02, 0.05, 0.09, 0.13];
    let mut samples = SampleSet::ward_grid(&rho_d, &alpha).on_grid(&grid, inst.view_deg);
    for (c, mut col) in samples.column_iter_mut().enumerate() {
        col *= 10f64.powi(c as i32 % 4 - 1);
    }
    let prior = WeightedSamples::equal(samples);
    let bins: Vec<f32> = grid.bins_deg().iter().map(|x| *x as f32).collect();
    let opts = ScaleFreeOptions { root: true, band_bins: Some(&bins), ..Default::default() };
    let two = train_zone(&h, &prior, &opts).unwrap();
    let one = train_zone(&h, &prior, &ScaleFreeOptions { band_bins: None, ..opts }).unwrap();
    // Without the grid, one table as before; the estimates are the same either way.
    assert!(one.band_bins.is_none() && one.maps.iter().all(|m| m.sigma_broad.is_none()));
    assert!(two.band_bins.is_some() && two.maps.iter().all(|m| m.sigma_broad.is_some()));
    assert!(one.maps.iter().zip(&two.maps).all(|(a, b)| a.w == b.w));
    // Every prior sample's reading states the table its estimate takes,
    // and both kinds occur (the narrowest Ward lobes read sharp, the
    // widest broad) with tables that differ.
    let mut kinds = [false; 2];
    for k in 0..prior.samples.ncols() {
        let v: Vec<f32> = (&h * prior.samples.column(k)).iter().map(|x| *x as f32).collect();
        let (est, sigma, _, c) = two.estimate_f32(&v);
        let broad = brdf_meter::band::is_broad(&bins, &est);
        kinds[usize::from(broad)] = true;
        let map = &two.maps[c];
        let table = if broad { map.sigma_broad.as_ref().unwrap() } else { &map.sigma_unit };
        let s: f32 = v.iter().sum();
        for j in 0..est.len() {
            assert_eq!(sigma[j], root_uncertainty(table[j] as f32, est[j], s), "sample {k} bin {j}");
        }
    }
    assert_eq!(kinds, [true, true]);
    assert!(two.maps.iter().any(|m| m.sigma_broad.as_ref().unwrap() != &m.sigma_unit));
}

#[test]
fn piecewise_trains_clusters_and_is_at_least_as_good_in_cross_validation() {
    let (h, prior) = setup();
    let plain = train_zone(&h, &prior, &ScaleFreeOptions::default()).unwrap();
    let pw = train_zone(&h, &prior, &ScaleFreeOptions { piecewise: true, ..Default::default() }).unwrap();
    assert!(pw.maps.len() >= 2 && pw.centroids.len() == pw.maps.len() * h.nrows());
    assert!(plain.cv_error.is_finite() && pw.cv_error.is_finite());
    assert!(
        train_zone(&h, &WeightedSamples::equal(prior.samples.columns(0, 4).into_owned()), &ScaleFreeOptions::default())
            .is_err()
    );
}
