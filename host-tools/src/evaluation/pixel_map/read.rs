//! One surface read at every pixel of the line as the device reads it, and
//! scored against its truth at each pixel's own view.

use super::*;

/// One surface simulated with the scene's every effect for `lines` lines,
/// read as the device reads it; per line and pixel the estimate and the
/// corrected readings.
pub(super) struct Read {
    /// `[line][pixel]`.
    pub(super) points: Vec<Vec<crate::device::reference::ExpectedPoint>>,
}

pub(super) fn read_surface(
    spec: &MapSpec,
    brdf: Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    lines: u64,
    seed: u64,
) -> anyhow::Result<Read> {
    // Lines 0.. of the scene (its LEDs drift with the frames since
    // calibration), each surface with its own noise draw.
    let mut scene = spec.scene.clone();
    if scene.noise().is_some() {
        crate::forward::scene::readings::set_noise_seed(&mut scene, seed)?;
    }
    let sim = Simulator::with_surface(&scene, brdf)?;
    let fs = scene.instrument.sensor.full_scale as u16;
    let points = (0..lines)
        .map(|l| {
            let frames = sim.raw_frames(l)?;
            Ok(expected_line(blob, &frames, fs, &spec.acq))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Read { points })
}

/// A scene's surface as one line of JSON, without the fields it leaves to
/// their defaults.
pub(super) fn surface_text(b: &crate::forward::brdf::BrdfSpec) -> String {
    match serde_json::to_value(b) {
        Ok(serde_json::Value::Object(mut m)) => {
            m.retain(|_, v| !v.is_null());
            serde_json::Value::Object(m).to_string()
        }
        _ => String::new(),
    }
}

/// Surface `b` read over the line for `lines` lines (noise seed `seed`) by
/// `blob`, and per pixel its BRDF scores (each the mean over the lines).
pub(super) fn score_lines(
    spec: &MapSpec,
    geo: &LineGeometry,
    b: &Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    lines: u64,
    seed: u64,
) -> anyhow::Result<(Read, Vec<SurfacePixel>)> {
    let read = read_surface(spec, b.clone(), blob, lines, seed)?;
    let scores = (0..geo.views.len())
        .map(|px| {
            let t = truth_at(b.as_ref(), &geo.views[px], &geo.grid);
            let lines = read.points.len().max(1) as f64;
            let mut acc = SurfacePixel::default();
            for line in &read.points {
                let sc = PointScore::of(blob, &geo.bins32, &t, &line[px], &geo.interp[px]);
                acc.error += sc.error / lines;
                acc.interpolation += sc.interpolation / lines;
                acc.covered += sc.covered / lines;
                let flagged = line[px].flags & flags::OUT_OF_PRIOR != 0;
                acc.out_of_prior += f64::from(u8::from(flagged)) / lines;
                acc.flag.add(sc.error, flagged);
            }
            acc
        })
        .collect();
    Ok((read, scores))
}

/// A surface's truth at a pixel's view: its binned reflectance factor on the grid.
pub(super) fn truth_at(
    b: &dyn Brdf,
    view: &nalgebra::Vector3<f64>,
    grid: &crate::forward::grid::AngleGrid,
) -> DVector<f64> {
    DVector::from_iterator(
        grid.n(),
        grid.bins_deg().iter().map(|t| binned_reflectance_at(b, *t, view, grid.step_deg())),
    )
}

/// One point read against its truth.
pub(super) struct PointScore {
    /// The estimate's BRDF error: RMS over the bins / the truth's peak.
    pub(super) error: f64,
    /// Linear interpolation's, on the same corrected readings.
    pub(super) interpolation: f64,
    /// Share of the bins within k = 2 of the uncertainty the frame states
    /// (`BlobView::point_uncertainty`, what `measure` writes).
    pub(super) covered: f64,
    /// Those uncertainties, per bin.
    pub(super) u: Vec<f32>,
    /// Interpolation's profile (its gloss is read from it).
    pub(super) profile: DVector<f64>,
}

impl PointScore {
    pub(super) fn of(
        blob: &BlobView<'_>,
        bins_deg: &[f32],
        truth: &DVector<f64>,
        pt: &crate::device::reference::ExpectedPoint,
        interp: &nalgebra::DMatrix<f64>,
    ) -> Self {
        let n = truth.len();
        let est = DVector::from_iterator(n, pt.values.iter().map(|x| f64::from(*x)));
        let profile = interp * DVector::from_iterator(pt.corrected.len(), pt.corrected.iter().map(|x| f64::from(*x)));
        let table = blob.band_table(bins_deg, &pt.values);
        let u: Vec<f32> = (0..n)
            .map(|j| {
                blob.point_uncertainty(table, (pt.zone as usize, pt.cluster as usize), j, pt.values[j], pt.sigma_scale)
            })
            .collect();
        let inside = (0..n).filter(|&j| (est[j] - truth[j]).abs() <= K * f64::from(u[j])).count();
        Self {
            error: peak_error(&est, truth),
            interpolation: peak_error(&profile, truth),
            covered: inside as f64 / n.max(1) as f64,
            u,
            profile,
        }
    }
}

/// A gloss tile read over its lines by the calibration on the whole prior.
pub(super) struct TileRead {
    pub(super) read: Read,
    /// Per pixel, its gloss by the definitions in three dimensions, GU.
    pub(super) gloss_truth: Vec<Option<f64>>,
    /// Per pixel, its BRDF scores (each the mean over the lines).
    pub(super) brdf: Vec<SurfacePixel>,
}

/// One surface's BRDF at one pixel (a tile's, the scene's own), each
/// figure its mean over the lines.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SurfacePixel {
    pub(super) error: f64,
    pub(super) interpolation: f64,
    pub(super) covered: f64,
    pub(super) out_of_prior: f64,
    pub(super) flag: FlagScore,
}

/// One pixel's counts over its held-out points.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PixelCounts {
    /// Points flagged out of prior.
    pub(super) out_of_prior: usize,
    /// Points flagged saturated.
    pub(super) saturated: usize,
    /// Points.
    pub(super) points: usize,
    /// Points whose estimate has a specular peak where the truth has one.
    pub(super) peaks: usize,
    /// Of them, peaks the pixel does not resolve.
    pub(super) unresolved: usize,
}

impl PixelCounts {
    pub(super) fn add(&mut self, o: Self) {
        self.out_of_prior += o.out_of_prior;
        self.saturated += o.saturated;
        self.points += o.points;
        self.peaks += o.peaks;
        self.unresolved += o.unresolved;
    }
}

/// Per pixel of the line: its view, and linear interpolation's weights
/// between the LEDs' centre angles there; the scene's grid.
pub(super) struct LineGeometry {
    /// The prior's samples on the grid at the scene's view (columns): what
    /// a material's nearest training sample is sought among.
    pub(super) prior: nalgebra::DMatrix<f64>,
    pub(super) views: Vec<nalgebra::Vector3<f64>>,
    pub(super) interp: Vec<nalgebra::DMatrix<f64>>,
    pub(super) grid: crate::forward::grid::AngleGrid,
    /// The grid's bins as the device holds them (f32).
    pub(super) bins32: Vec<f32>,
}

/// Per reading, whether the result of `points` (the centre zones', as
/// `measure` states it) covers the mean of `truth` over their pixels: 1
/// or 0, NaN without a result or a truth.
fn result_covered(
    blob: &BlobView<'_>,
    centre: &[usize],
    geo: &LineGeometry,
    points: Vec<crate::output::points::Point>,
    truth: &[Vec<f64>; 3],
) -> [f64; 3] {
    let points = crate::output::points::Points {
        source: "estimate",
        calibration_crc: blob.crc(),
        view_deg: 0.0,
        peak_resolution_deg: None,
        pixel_peak_resolution_deg: Vec::new(),
        peak_factors: None,
        bins_deg: geo.bins32.clone(),
        points,
    };
    let result = crate::device::measurement_result::measurement_result(blob, centre, &points);
    std::array::from_fn(|k| {
        let t = truth[k].iter().sum::<f64>() / truth[k].len().max(1) as f64;
        match result.readings.iter().find(|r| r.reading == brdf_meter::gloss::NAMES[k]) {
            Some(r) if t.is_finite() => f64::from(u8::from(r.covers(t))),
            _ => f64::NAN,
        }
    })
}

/// Material `b` (named `name`) read on the whole line by `blob` for the
/// spec's lines (noise seed `seed`): its row (with the flag's score over
/// its points), per pixel its flag counts, and its peaks.
pub(super) fn read_material(
    spec: &MapSpec,
    geo: &LineGeometry,
    name: &str,
    b: &Arc<dyn Brdf>,
    blob: &BlobView<'_>,
    seed: u64,
) -> anyhow::Result<MaterialRead> {
    let p = geo.views.len();
    let mut peaks = PeakTally::default();
    let read = read_surface(spec, b.clone(), blob, spec.lines, seed)?;
    let mut err = vec![0.0; p];
    let mut ierr = vec![0.0; p];
    let mut fl = vec![PixelCounts::default(); p];
    let (mut g_true, mut g_est, mut g_int) = (vec![0.0; p], vec![0.0; p], vec![0.0; p]);
    // Per pixel, the mean haze and distinctness over the lines: the device's and interpolation's.
    let (mut hd_est, mut hd_int) = (vec![[0.0f64; 2]; p], vec![[0.0f64; 2]; p]);
    let mut hd_true = vec![[0.0f64; 2]; p];
    let mut covered = vec![0.0; p];
    // Per pixel and reading: lines with the reading, and of them within k = 2.
    let mut readings_in = vec![[(0usize, 0usize); 3]; p];
    let mut flag = FlagScore::default();
    let mut flag_errors = FlagErrors::default();
    // The result a user states of the material, as `measure` states it
    // (`device::measurement_result`) of the centre zones' points, against
    // the truth's mean over their pixels.
    let centre = crate::device::measurement_result::centre_zones(blob);
    let mut result_points = Vec::new();
    let mut result_truth: [Vec<f64>; 3] = Default::default();
    for (px, ((e, ie), c)) in err.iter_mut().zip(&mut ierr).zip(&mut fl).enumerate() {
        let in_result = centre.contains(&blob.zone_of_pixel(px));
        let true_readings = model_readings(b.as_ref(), &geo.views[px]);
        if in_result {
            for (t, x) in result_truth.iter_mut().zip(true_readings) {
                t.push(x);
            }
        }
        g_true[px] = true_readings[brdf_meter::gloss::SPECULAR_GU];
        hd_true[px] = [true_readings[brdf_meter::gloss::HAZE_HU], true_readings[brdf_meter::gloss::DISTINCTNESS]];
        let view_deg = geo.views[px].z.clamp(-1.0, 1.0).acos().to_degrees();
        let truth = truth_at(b.as_ref(), &geo.views[px], &geo.grid);
        let truth32: Vec<f32> = truth.iter().map(|x| *x as f32).collect();
        for line in &read.points {
            let pt = &line[px];
            let score = PointScore::of(blob, &geo.bins32, &truth, pt, &geo.interp[px]);
            let profile: Vec<f32> = score.profile.iter().map(|x| *x as f32).collect();
            let at = PixelPeaks {
                view_deg,
                resolution_deg: blob.peak_resolution_at(px).map(f64::from),
                factors: blob.peak_factors(),
            };
            if let Some(unresolved) = peaks.add(&geo.bins32, &truth32, pt, &score.u, &profile, at) {
                c.peaks += 1;
                c.unresolved += usize::from(unresolved);
            }
            *e += score.error / spec.lines as f64;
            *ie += score.interpolation / spec.lines as f64;
            covered[px] += score.covered / spec.lines as f64;
            g_est[px] += f64::from(pt.readings[brdf_meter::gloss::SPECULAR_GU]) / spec.lines as f64;
            let li = profile_scaled_readings(&score.profile, geo.grid.bins_deg(), view_deg);
            g_int[px] += li.map_or(f64::NAN, |l| l[0]) / spec.lines as f64;
            for (r, k) in [brdf_meter::gloss::HAZE_HU, brdf_meter::gloss::DISTINCTNESS].into_iter().enumerate() {
                hd_est[px][r] += f64::from(pt.readings[k]) / spec.lines as f64;
                hd_int[px][r] += li.map_or(f64::NAN, |l| l[k]) / spec.lines as f64;
            }
            if in_result {
                result_points.push(crate::output::points::Point {
                    line: None,
                    pixel: Some(px as u64),
                    zone: pt.zone,
                    cluster: pt.cluster,
                    flags: pt.flags,
                    rho: pt.values.clone(),
                    u_rho: score.u.clone(),
                    readings: pt.readings,
                    u_readings: pt.reading_sigma,
                });
            }
            for (k, (n, inside)) in readings_in[px].iter_mut().enumerate() {
                let (r, u) = (f64::from(pt.readings[k]), f64::from(pt.reading_sigma[k]));
                if r.is_finite() && true_readings[k].is_finite() {
                    *n += 1;
                    // An uncertainty that is not stated (NaN) covers nothing.
                    *inside += usize::from((r - true_readings[k]).abs() <= 2.0 * u);
                }
            }
            let flagged = pt.flags & flags::OUT_OF_PRIOR != 0;
            c.out_of_prior += usize::from(flagged);
            flag.add(score.error, flagged);
            flag_errors.add(score.error, flagged);
            c.saturated += usize::from(pt.flags & flags::SATURATED != 0);
            c.points += 1;
        }
    }
    let row = MaterialRow {
        name: name.to_string(),
        error: err,
        interpolation: ierr,
        gloss_true: g_true,
        gloss: g_est,
        gloss_interpolation: g_int,
        bin_coverage: covered,
        haze_distinctness_error: [&hd_est, &hd_int]
            .map(|read| read.iter().zip(&hd_true).map(|(r, t)| [(r[0] - t[0]).abs(), (r[1] - t[1]).abs()]).collect()),
        reading_coverage: readings_in
            .iter()
            .map(|px| px.map(|(n, inside)| if n == 0 { f64::NAN } else { inside as f64 / n as f64 }))
            .collect(),
        result_covered: result_covered(blob, &centre, geo, result_points, &result_truth),
        flag,
        flag_errors,
        nearest_training: None,
    };
    Ok((row, fl, peaks))
}
