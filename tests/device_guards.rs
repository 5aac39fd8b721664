//! Device guards: corrected readings that are saturated,
//! zero, negative or non-finite are flagged per point, and no NaN or infinity
//! ever reaches a streamed frame - including when W itself is so large that
//! `W v` overflows f32 (policy: the point is zeroed and flagged NON_FINITE,
//! `brdf_meter::estimate::guard_estimate`).
use brdf_meter::acquire::{MIN_SIGNAL_COUNTS, RawLine, correct_line, correct_point_into};
use brdf_meter::blob::{BlobView, Dims};
use brdf_meter::estimate::guard_estimate;
use brdf_meter::kernel::mat_vec_f32_slice;
use brdf_meter::nalgebra::SVector;
use brdf_meter::platform::host_sim::SimFlash;
use brdf_meter::protocol::flags;
use brdf_meter::test_blobs::{sign_for_tests, test_blob_with};
use host_tools::device::link::Client;
use host_tools::device::reference::expected_line;
use host_tools::forward::scene::frames::analytic_scene;
use system_tests::sim::{FULL_SCALE, M, N, P, SLOT_LEN, SimDevice};

/// A tiny deterministic generator (the tests package has no rand).
struct XorShift(u64);
impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// The flags a corrected point must carry, from first principles.
fn expected_flags(dark: u16, lit: &[u16], white: &[f32], full_scale: u16) -> u8 {
    let mut f = 0;
    if dark >= full_scale || lit.iter().any(|l| *l >= full_scale) {
        f |= flags::SATURATED;
    }
    // Zero or negative (or tiny) dark-corrected signal.
    if lit.iter().any(|l| (*l as f32 - dark as f32) < MIN_SIGNAL_COUNTS) {
        f |= flags::UNDER_EXPOSED;
    }
    if lit.iter().zip(white).any(|(l, w)| !((*l as f32 - dark as f32) / w).is_finite()) {
        f |= flags::NON_FINITE;
    }
    f
}

#[test]
fn each_defect_is_flagged_on_its_own_point_only() {
    const PX: usize = 8;
    const MM: usize = 3;
    let mut raw = RawLine::<MM, PX>::new();
    let mut white = [[1000.0f32; MM]; PX];
    for p in 0..PX {
        raw.dark[p] = 100;
        for i in 0..MM {
            raw.lit[i][p] = 1100 + 10 * i as u16;
        }
    }
    let fs = 4095;
    raw.lit[1][1] = fs; // saturated reading
    raw.dark[2] = fs; // saturated dark (every reading then <= 0)
    raw.lit[0][3] = 100; // zero signal
    raw.lit[2][4] = 60; // negative signal
    white[5][1] = f32::from_bits(1); // smallest subnormal white: 1000 / 1e-45 = inf
    raw.lit[0][6] = 104; // 4 counts: below MIN_SIGNAL_COUNTS
    let mut v = [SVector::<f32, MM>::zeros(); PX];
    let mut fl = [0u8; PX];
    correct_line(&raw, &white, None, fs, &brdf_meter::acquire::AcqConfig::default(), &mut v, &mut fl);
    assert_eq!(fl[0], 0);
    assert_eq!(fl[1], flags::SATURATED);
    assert_eq!(fl[2], flags::SATURATED | flags::UNDER_EXPOSED);
    assert_eq!(fl[3], flags::UNDER_EXPOSED);
    assert_eq!(v[3][0], 0.0);
    assert_eq!(fl[4], flags::UNDER_EXPOSED);
    assert!(v[4][2] < 0.0);
    assert_eq!(fl[5], flags::NON_FINITE);
    assert!(v[5][1].is_infinite());
    assert_eq!(fl[6], flags::UNDER_EXPOSED);
    assert_eq!(fl[7], 0);
}

#[test]
fn correction_flags_match_first_principles_on_random_points() {
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    let fs = 4095u16;
    for case in 0..20_000 {
        let m = 1 + rng.below(12) as usize;
        // Bias towards the edges: full scale, dark above lit, tiny whites.
        let pick = |rng: &mut XorShift| match rng.below(6) {
            0 => fs,
            1 => rng.below(16) as u16,
            _ => rng.below(fs as u64 + 1) as u16,
        };
        let dark = pick(&mut rng);
        let lit: Vec<u16> = (0..m).map(|_| pick(&mut rng)).collect();
        let white: Vec<f32> = (0..m)
            .map(|_| match rng.below(5) {
                0 => f32::from_bits(1 + rng.below(1 << 20) as u32), // subnormal
                1 => f32::MIN_POSITIVE,
                _ => 1.0 + rng.below(5000) as f32,
            })
            .collect();
        let mut v = vec![0.0f32; m];
        let f = correct_point_into(dark, &lit, &white, fs, &[], None, &mut v);
        assert_eq!(f, expected_flags(dark, &lit, &white, fs), "case {case}: dark {dark}, lit {lit:?}, white {white:?}");
        // Unflagged readings are finite and positive.
        if f == 0 {
            assert!(v.iter().all(|x| x.is_finite() && *x > 0.0), "case {case}: {v:?}");
        }
    }
}

#[test]
fn guard_zeroes_and_flags_non_finite_estimates_only() {
    let mut ok = [1.0f32, -2.5, 3.0e38, f32::MIN_POSITIVE];
    assert_eq!(guard_estimate(&mut ok), 0);
    assert_eq!(ok, [1.0, -2.5, 3.0e38, f32::MIN_POSITIVE]);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut r = [1.0f32, bad, 2.0];
        assert_eq!(guard_estimate(&mut r), flags::NON_FINITE);
        assert_eq!(r, [0.0; 3]);
    }
    // A huge but finite W: the f32 product overflows; the guard catches it.
    let (n, m) = (4, 7);
    let w: Vec<f32> = (0..n * m).map(|k| if k % 3 == 0 { -3.0e38 } else { 3.0e38 }).collect();
    let v = [0.9f32, 1.1, 0.7, 1.3, 0.2, 0.8, 1.0];
    let mut rho = vec![0.0f32; n];
    mat_vec_f32_slice(&w, &v, &mut rho);
    assert!(rho.iter().any(|x| !x.is_finite()), "the kernel must overflow here: {rho:?}");
    assert_eq!(guard_estimate(&mut rho), flags::NON_FINITE);
    assert!(rho.iter().all(|x| *x == 0.0));
}

const ZONES: usize = 4;

/// A signed blob like `brdf_meter::test_blobs::test_blob`, but zone `huge_zone`'s W is
/// +-3e38 (finite, valid, and certain to overflow f32 in `W v`) and pixel
/// `tiny_white_px` has a subnormal white reference for reading 0.
fn hostile_blob(huge_zone: usize, tiny_white_px: usize) -> Vec<u8> {
    let dims = Dims { n: N, m: M, zones: ZONES, pixels: P };
    let mut white: Vec<f32> = (0..P * M).map(|k| 900.0 + ((k * 37) % 200) as f32).collect();
    white[tiny_white_px * M] = f32::from_bits(1);
    let mats: Vec<f32> = (0..ZONES * N * M)
        .map(|k| {
            let z = k / (N * M);
            if z == huge_zone { if k % 2 == 0 { 3.0e38 } else { 2.0e38 } } else { ((k as f32) * 0.731).sin() * 0.5 }
        })
        .collect();
    let order: Vec<u8> = (0..M as u8).collect();
    sign_for_tests(&test_blob_with(dims, &order, &white, &mats))
}

#[test]
fn no_nan_or_infinity_reaches_a_streamed_frame() {
    let huge_zone = 2;
    let tiny_px = 9;
    let b = hostile_blob(huge_zone, tiny_px);
    let view = BlobView::parse(&b).unwrap();
    let mut c = Client::new(SimDevice::boot(SimFlash::new(2 * SLOT_LEN as usize), ZONES)).unwrap();
    c.format = brdf_meter::protocol::StreamFormat::LOSSLESS;
    c.provision(&b, |_, _| {}).unwrap();
    let mut scene = analytic_scene(&view, 2, FULL_SCALE);
    for line in scene.iter_mut() {
        let dark = |line: &Vec<Vec<u16>>, p: usize| line[0][p];
        line[1][3] = FULL_SCALE; // pixel 3: reading 0 saturated
        for f in 1..=M {
            line[f][5] = dark(line, 5); // pixel 5: zero signal
            line[f][6] = dark(line, 6) - 10; // pixel 6: negative signal
        }
        line[0][7] = FULL_SCALE; // pixel 7: dark saturated
        line[1][tiny_px] = dark(line, tiny_px) + 1000; // 1000 / subnormal white = inf
    }
    c.load_scene(&scene).unwrap();
    let pts = c.measure(2).unwrap();
    assert_eq!(pts.len(), 2 * P);
    for (k, p) in pts.iter().enumerate() {
        let px = k % P;
        assert!(p.values.iter().all(|x| x.is_finite()), "point {px} of line {} streamed {:?}", p.line, p.values);
        // The host's reproduction (same correction, kernel and guard) agrees bit for bit.
        let want = &expected_line(&view, &scene[k / P], FULL_SCALE, &system_tests::sim::ACQ)[px];
        assert_eq!(system_tests::meta_bits(p), system_tests::expected_meta_bits(want), "point {px}");
        let got: Vec<u32> = p.values.iter().map(|x| x.to_bits()).collect();
        let exp: Vec<u32> = want.values.iter().map(|x| x.to_bits()).collect();
        assert_eq!(got, exp, "point {px}");
        let in_huge = view.zone_of_pixel(px) == huge_zone;
        let expect = match px {
            3 => flags::SATURATED,
            5 | 6 => flags::UNDER_EXPOSED,
            7 => flags::SATURATED | flags::UNDER_EXPOSED,
            _ if px == tiny_px => flags::NON_FINITE,
            _ if in_huge => flags::NON_FINITE,
            _ => 0,
        };
        assert_eq!(p.flags, expect, "flags of point {px}");
        if expect & flags::NON_FINITE != 0 {
            assert!(p.values.iter().all(|x| *x == 0.0), "a non-finite point is zeroed: {:?}", p.values);
        } else if expect == 0 {
            assert!(p.values.iter().any(|x| *x != 0.0), "point {px} should carry an estimate");
        }
    }
}
