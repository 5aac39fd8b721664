//! The decision's tests: per point, per line, across lines.
use super::super::recipe::{RecipeData, RecipeSettings, check_settings, group_len, write};
use super::point::select;
use super::*;
use crate::protocol::flags;
use crate::shape::READINGS;

const M: usize = 3;
const P: usize = 8;

/// A recipe whose reference is v = 1 at every pixel, sd 0.1, no
/// correlation, gloss gradient 10 GU per unit of reading 0.
fn recipe(min_pixels: u16, min_lines: u16) -> Vec<u8> {
    let mut settings = super::super::recipe::tests::settings();
    settings.threshold_on = 25.0; // 5 sd
    settings.threshold_off = 9.0;
    settings.windows = [[-2.0, 2.0], [f32::NEG_INFINITY, f32::INFINITY], [f32::NEG_INFINITY, f32::INFINITY]];
    settings.ewma_lambda = 0.5;
    settings.ewma_limit = 0.5;
    recipe_with(min_pixels, min_lines, settings)
}

/// [`recipe`]'s reference with `settings` and the minimum sizes.
fn recipe_with(min_pixels: u16, min_lines: u16, mut settings: RecipeSettings) -> Vec<u8> {
    let mut group = vec![0.0f32; group_len(M)];
    // Identity whitening, packed lower triangle.
    let mut k = 0;
    for i in 0..M - 1 {
        for j in 0..=i {
            group[k] = if i == j { 1.0 } else { 0.0 };
            k += 1;
        }
    }
    group[k] = 10.0; // d gloss / d f_0
    settings.min_pixels = min_pixels;
    settings.min_lines = min_lines;
    write(&RecipeData {
        pixels: P,
        m: M,
        group_starts: vec![0],
        group_values: vec![group],
        pixel_values: (0..P).map(|_| [1.0, 1.0, 1.0, 10.0, 10.0, 1.0 / 3.0, 1.0 / P as f32].to_vec()).collect(),
        settings,
    })
    .unwrap()
}

fn line(values: &[(usize, [f32; M])]) -> Vec<SVector<f32, M>> {
    let mut v = vec![SVector::from([1.0f32; M]); P];
    for (p, x) in values {
        v[*p] = SVector::from(*x);
    }
    v
}

#[test]
fn select_finds_the_kth_smallest() {
    let mut seed = 7u32;
    for n in 1..40 {
        let v: Vec<f32> = (0..n)
            .map(|_| {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                ((seed >> 16) % 9) as f32
            })
            .collect();
        let mut sorted = v.clone();
        sorted.sort_by(f32::total_cmp);
        for (k, want) in sorted.iter().enumerate() {
            assert_eq!(select(&mut v.clone(), k), *want, "n {n}, k {k}, {v:?}");
        }
    }
}

#[test]
fn point_statistics_are_the_distance_and_the_gradient() {
    let bytes = recipe(1, 1);
    let r = RecipeView::parse(&bytes).unwrap();
    let s = point_stat_at(&r, 0, 3, &[1.3, 0.9, 0.8], 1.0);
    assert!((s.d2 - (9.0 + 1.0)).abs() < 1e-4, "{}", s.d2);
    assert!((s.delta[0] - 3.0).abs() < 1e-5);
}

#[test]
fn a_point_within_the_leaving_thresholds_is_out_at_neither() {
    // The decision's fast test (`Limits::within`) stands for both
    // classifications; it holds for any settings the recipe allows.
    let mut x = 0x9E37_79B9u32;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x as f32 / u32::MAX as f32
    };
    let edges = [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    let mut within = 0;
    for case in 0..20_000 {
        let mut s = super::super::recipe::tests::settings();
        s.threshold_on = 1.0 + 40.0 * next();
        s.threshold_off = s.threshold_on * (0.05 + 0.95 * next());
        s.window_hysteresis = 0.05 + 0.95 * next();
        for w in s.windows.iter_mut() {
            *w = if next() < 0.2 { [f32::NEG_INFINITY, f32::INFINITY] } else { [-3.0 * next(), 3.0 * next()] };
            if w[0] == w[1] {
                w[1] = 1.0;
            }
        }
        check_settings(&s).unwrap();
        let (entering, leaving) = (Limits::of(&s, false), Limits::of(&s, true));
        let mut value = |scale: f32| if next() < 0.05 { edges[case % edges.len()] } else { scale * (next() - 0.5) };
        let stat = PointStat { d2: value(8.0).abs(), delta: [value(4.0), value(4.0), value(4.0)] };
        // On a threshold exactly, now and then.
        let stat = if case % 7 == 0 { PointStat { d2: s.threshold_off, ..stat } } else { stat };
        // (Not within is no claim: a NaN change is neither, and the
        // decision then asks `kind`, as it always did.)
        if leaving.within(&stat) {
            within += 1;
            assert_eq!((entering.kind(&stat, 0), leaving.kind(&stat, 0)), (None, None), "{stat:?} {s:?}");
        }
    }
    assert!(within > 2_000 && within < 18_000, "{within}");
}

#[test]
fn only_the_readings_with_a_window_are_worked_out() {
    let off = [f32::NEG_INFINITY, f32::INFINITY];
    let mut s = super::super::recipe::tests::settings();
    for (windows, readings) in [
        ([off, off, off], 1),
        ([[-2.0, 2.0], off, off], 1),
        ([off, [-1.0, f32::INFINITY], off], 2),
        ([[-2.0, 2.0], off, [f32::NEG_INFINITY, 3.0]], 3),
    ] {
        s.windows = windows;
        for leaving in [false, true] {
            assert_eq!(Limits::of(&s, leaving).readings(), readings, "{windows:?}");
        }
    }
    // The changes worked out are those of all three, bit for bit; the
    // rest are 0.
    let bytes = recipe(1, 1);
    let r = RecipeView::parse(&bytes).unwrap();
    let px = PixelRef::<M>::of(&r, 3);
    let mut group = [0.0f32; MAX_GROUP_VALUES];
    let mut room = [0.0f32; MAX_GROUP_VALUES];
    group[..group_len(M)].copy_from_slice(group_values(&r, 0, &mut room));
    for (k, g) in group.iter_mut().take(group_len(M)).enumerate() {
        *g += 0.37 * k as f32 - 1.1;
    }
    let v = [1.3, 0.9, 0.8];
    let all = point_stat(&px.mean, &px.inv_sd, &group, &v, 1.07, READINGS);
    assert!(all.delta.iter().all(|d| *d != 0.0), "{all:?}");
    for readings in 1..=READINGS {
        let some = point_stat(&px.mean, &px.inv_sd, &group, &v, 1.07, readings);
        assert_eq!(some.d2.to_bits(), all.d2.to_bits());
        for (i, (a, b)) in some.delta.iter().zip(&all.delta).enumerate() {
            assert_eq!(a.to_bits(), if i < readings { b.to_bits() } else { 0 }, "{readings}: {i}");
        }
    }
}

#[test]
fn a_recipe_read_in_place_decides_as_one_decoded() {
    // On the device the recipe is aligned and read in place; a host's
    // byte slice may not be, and is decoded value by value.
    let bytes = recipe(2, 1);
    let mut shifted = vec![0u8; bytes.len() + 1];
    shifted[1..].copy_from_slice(&bytes);
    let (aligned, unaligned) = (RecipeView::parse(&bytes).unwrap(), RecipeView::parse(&shifted[1..]).unwrap());
    assert!(aligned.pixel_table().is_some() != unaligned.pixel_table().is_some());
    let (mut a, mut b) = (Inspector::<P>::new(), Inspector::<P>::new());
    let lines = [
        line(&[]),
        line(&[(2, [1.6, 1.0, 1.0]), (3, [1.5, 1.0, 1.0]), (4, [1.3, 1.0, 1.0])]),
        line(&[(3, [1.25, 1.0, 1.0]), (5, [0.7, 1.2, 1.0])]),
        line(&[(0, [f32::NAN, 1.0, 1.0]), (6, [1.0, 1.9, 0.2]), (7, [1.0, 1.9, 0.2])]),
    ];
    for (k, v) in lines.iter().enumerate() {
        let flags = [0u8; P];
        let (va, vb) =
            (a.line(&aligned, k as u32, v, &flags, |_| false), b.line(&unaligned, k as u32, v, &flags, |_| false));
        assert_eq!(format!("{va:?}"), format!("{vb:?}"));
    }
    assert!(a.counters().defects > 0);
}

#[test]
fn runs_kinds_minimum_size_and_hysteresis() {
    let bytes = recipe(2, 1);
    let r = RecipeView::parse(&bytes).unwrap();
    let mut ins = Inspector::<P>::new();
    let flags = [0u8; P];
    // One pixel far out: below the minimum size, not a defect.
    let v = ins.line(&r, 0, &line(&[(2, [1.0, 2.0, 1.0])]), &flags, |_| false);
    assert!(!v.rejected() && v.runs.is_empty());
    // Pixels 4, 5 with gloss +3 GU (f0 + 0.3, d2 = 11.25 below the threshold): gloss high.
    let v = ins.line(&r, 1, &line(&[(4, [1.3, 0.85, 0.85]), (5, [1.3, 0.85, 0.85])]), &flags, |_| false);
    assert!(v.rejected());
    assert_eq!(
        v.runs.as_slice(),
        &[DefectRun { first: 4, len: 2, kind: DefectKind::GlossHigh, peak_d2: v.runs[0].peak_d2 }]
    );
    // Hysteresis: +1.8 GU stays out for pixels that were out (window x 0.8 = 1.6) ...
    let v = ins.line(&r, 2, &line(&[(4, [1.18, 0.91, 0.91]), (5, [1.18, 0.91, 0.91])]), &flags, |_| false);
    assert!(v.rejected());
    // ... but does not bring in pixels that were not.
    let v = ins.line(&r, 3, &line(&[(0, [1.18, 0.91, 0.91]), (1, [1.18, 0.91, 0.91])]), &flags, |_| false);
    assert!(!v.rejected());
    // Out-of-prior is asked only of a defect's pixels, until one says
    // yes, and wins over the window kinds.
    let mut asked = Vec::new();
    let v = ins.line(&r, 4, &line(&[(6, [1.0, 2.0, 1.0]), (7, [0.7, 1.0, 1.0])]), &flags, |p| {
        asked.push(p);
        p == 6
    });
    assert_eq!(asked, [6]);
    assert_eq!(v.runs[0].kind, DefectKind::OutOfPrior);
    // Saturation is unreadable whatever the readings.
    let mut f = [0u8; P];
    f[0] = flags::SATURATED;
    f[1] = flags::SATURATED;
    let v = ins.line(&r, 5, &line(&[]), &f, |_| false);
    assert_eq!((v.runs[0].first, v.runs[0].kind), (0, DefectKind::Unreadable));
    let c = ins.counters();
    assert_eq!((c.lines, c.rejected, c.defects), (6, 4, 4));
}

#[test]
fn hysteresis_along_the_line_extends_a_defect_but_never_starts_one() {
    let bytes = recipe(3, 1);
    let r = RecipeView::parse(&bytes).unwrap();
    let (high, held, inside) = ([1.3, 0.85, 0.85], [1.18, 0.91, 0.91], [1.1, 0.95, 0.95]);
    let verdict = |values: &[(usize, [f32; M])]| Inspector::<P>::new().line(&r, 0, &line(values), &[0; P], |_| false);
    // +3, +1.8, +3 GU: the middle pixel is inside the entering window
    // (2 GU) but out of the leaving one (1.6 GU), so the three are one defect.
    let v = verdict(&[(3, high), (4, held), (5, high)]);
    assert_eq!(
        v.runs.as_slice(),
        &[DefectRun { first: 3, len: 3, kind: DefectKind::GlossHigh, peak_d2: v.runs[0].peak_d2 }]
    );
    // A neighbour at +1 GU is inside both: two pixels stay below the minimum.
    assert!(!verdict(&[(3, high), (4, high), (5, inside)]).rejected());
    // Pixels out only at the leaving thresholds are never a defect on their own.
    assert!(!verdict(&[(3, held), (4, held), (5, held), (6, held)]).rejected());
    // A format 1 recipe is decided as it was taught: every pixel at the entering thresholds.
    let mut old = *RecipeView::parse(&bytes).unwrap().settings();
    old.along_line_hysteresis = false;
    let bytes = recipe_with(3, 1, old);
    let r = RecipeView::parse(&bytes).unwrap();
    assert_eq!(super::super::recipe::FORMAT_VERSION_ENTERING_RUNS, u16::from_le_bytes([bytes[4], bytes[5]]));
    let line = line(&[(3, high), (4, held), (5, high)]);
    assert!(!Inspector::<P>::new().line(&r, 0, &line, &[0; P], |_| false).rejected());
}

#[test]
fn a_defect_must_last_its_minimum_lines() {
    let bytes = recipe(1, 3);
    let r = RecipeView::parse(&bytes).unwrap();
    let mut ins = Inspector::<P>::new();
    let bad = line(&[(1, [1.0, 3.0, 1.0])]);
    let verdicts: Vec<bool> = (0..4).map(|l| ins.line(&r, l, &bad, &[0; P], |_| false).rejected()).collect();
    assert_eq!(verdicts, [false, false, true, true]);
    assert!(!ins.line(&r, 4, &line(&[]), &[0; P], |_| false).rejected());
}

#[test]
fn drift_raises_the_alarm_once_and_clears() {
    let bytes = recipe(1, 1);
    let r = RecipeView::parse(&bytes).unwrap();
    let mut ins = Inspector::<P>::new();
    // Every pixel +0.9 GU (inside the window): EWMA 0.45, 0.675 -> alarm on the second line.
    let drifted = vec![SVector::from([1.09f32, 0.955, 0.955]); P];
    let a = ins.line(&r, 0, &drifted, &[0; P], |_| false);
    let b = ins.line(&r, 1, &drifted, &[0; P], |_| false);
    assert_eq!((a.flags & verdict::DRIFT_ALARM, b.flags & verdict::DRIFT_ALARM), (0, verdict::DRIFT_ALARM));
    assert!(!b.rejected());
    let _ = ins.line(&r, 2, &drifted, &[0; P], |_| false);
    for l in 3..8 {
        ins.line(&r, l, &line(&[]), &[0; P], |_| false);
    }
    assert_eq!(ins.counters().drift_alarms, 1);
    assert_eq!(ins.line(&r, 9, &line(&[]), &[0; P], |_| false).flags & verdict::DRIFT_ALARM, 0);
}
