//! Raw frames as the instrument's sensor delivers them, `[line][frame][pixel]`
//! (frame 0 dark, 1 + k under LED k), for a simulated instrument (the QEMU
//! firmware, the host simulation): lines of a scene from the scene simulator,
//! and a simple analytic pattern.
//!
//! The analytic pattern (a diffuse base plus a specular lobe that moves along
//! the line) exercises every pixel, zone and LED with distinct values, which
//! is what the link and bit-exactness checks need.
use brdf_meter::blob::BlobView;

/// Raw frames of a scene: `[line][frame][pixel]`, frame 0 dark, 1 + k under LED k.
pub type SceneFrames = Vec<Vec<Vec<u16>>>;

/// One line's frames (as a scene serves them: per exposure level, the
/// dark frame then one per LED by index) in the order the acquisition
/// reads them, as `brdf_meter::acquire::RawLine::from_le_frames` takes
/// them: per level (the long one, then `shorter` shorter ones) the dark
/// frame and the LED frames in the calibration's reading order, u16 LE.
/// How the QEMU benches are fed a recorded line.
pub fn reading_order_le(view: &BlobView<'_>, frames: &[Vec<u16>], shorter: usize) -> Vec<u8> {
    let per_level = view.dims().m + 1;
    let mut out = Vec::new();
    let mut put = |f: &Vec<u16>| out.extend(f.iter().flat_map(|x| x.to_le_bytes()));
    for level in 0..=shorter {
        let base = level * per_level;
        put(&frames[base]);
        for &led in view.led_order() {
            put(&frames[base + 1 + led as usize]);
        }
    }
    out
}

/// A scene of `lines` lines for the instrument `blob` describes: raw counts
/// are `dark + white * reflectance`, with the blob's white reference (so a
/// perfect diffuser reads its white value), clamped to `full_scale`.
#[allow(clippy::needless_range_loop)] // p indexes every frame of the line
pub fn analytic_scene(blob: &BlobView<'_>, lines: usize, full_scale: u16) -> SceneFrames {
    let d = blob.dims();
    let order = blob.led_order();
    (0..lines)
        .map(|l| {
            let mut frames = vec![vec![0u16; d.pixels]; d.m + 1];
            for p in 0..d.pixels {
                let dark = 40 + ((p * 7 + l * 3) % 23) as u16;
                frames[0][p] = dark;
                for (i, &led) in order.iter().enumerate() {
                    let x = p as f32 / d.pixels.max(2) as f32;
                    let lobe_at = (l as f32 * 0.37 + x) * (d.m as f32 - 1.0) % d.m as f32;
                    let diff = 0.15 + 0.5 * x;
                    let spec = 0.6 * (-((i as f32 - lobe_at).powi(2)) / 0.8).exp();
                    let counts = dark as f32 + blob.white(p, i) * (diff + spec);
                    frames[led as usize + 1][p] = counts.round().clamp(0.0, full_scale as f32) as u16;
                }
            }
            frames
        })
        .collect()
}

/// The patent-profile scene (host-tools' scene simulator) with a line sensor
/// of `pixels` pixels: what the QEMU instrument simulates by default.
pub fn patent_scene(pixels: usize) -> super::Scene {
    let mut s = super::Scene::patent_profile();
    s.instrument.sensor.pixels = pixels;
    // The simulated device has the board's 12-bit converter: a gain that
    // keeps the patent surface's brightest reading (~48 white levels at
    // gain 1) inside it.
    s.instrument.sensor.gain = PATENT_SCENE_GAIN;
    s
}

/// The patent scene's gain on the simulated device: its brightest reading
/// about 3,800 of the 4,095 counts.
pub const PATENT_SCENE_GAIN: f64 = 80.0;

/// Raw frames of `lines` lines of `scene` from host-tools' scene simulator.
pub fn scene_frames(scene: &super::Scene, lines: usize) -> anyhow::Result<SceneFrames> {
    scene_frames_from(scene, 0, lines)
}

/// Raw frames of scene lines `first..first + lines` (the line is the time
/// since calibration, for the LEDs' drift, and the noise draw's). The
/// scene's rays and white reference are prepared once, not per line.
pub fn scene_frames_from(scene: &super::Scene, first: u64, lines: usize) -> anyhow::Result<SceneFrames> {
    frames_of(&super::Simulator::new(scene)?, first, lines)
}

fn frames_of(sim: &super::Simulator, first: u64, lines: usize) -> anyhow::Result<SceneFrames> {
    (first..first + lines as u64).map(|l| sim.raw_frames(l)).collect()
}

/// A scene named on the command line for a simulated device, and which of
/// its lines to load.
#[derive(Clone, Copy, Debug)]
pub struct NamedScene<'a> {
    /// `analytic`, `patent` or a scene TOML file.
    pub spec: &'a str,
    /// The first scene line loaded (the time since calibration).
    pub first_line: u64,
    /// Another surface under the scene's instrument (a scene's
    /// `surface.brdf`, [`super::Scene::with_surface`]).
    pub surface: Option<&'a str>,
}

/// A scene named on the command line, loaded, checked against the
/// calibration and simulated once, so a device can be given its lines
/// batch by batch ([`PreparedScene::frames`]).
pub struct PreparedScene {
    /// `None`: the analytic pattern, made from the calibration.
    sim: Option<super::Simulator>,
    /// For the user, when the device reads a cut of the scene's line.
    pub note: Option<String>,
}

impl PreparedScene {
    /// `named`'s scene (`analytic` ([`analytic_scene`]), `patent`
    /// ([`patent_scene`]) or a scene TOML file, its surface replaced when
    /// `named` says so) for the calibration `blob`'s pixel count, refused
    /// when it is not for the calibration's optics ([`check_optics`]).
    pub fn new(named: NamedScene<'_>, blob: &BlobView<'_>) -> anyhow::Result<Self> {
        use anyhow::Context;
        let pixels = blob.dims().pixels;
        let simulated = |s: super::Scene, note| -> anyhow::Result<Self> {
            let s = match named.surface {
                Some(spec) => s.with_surface(spec)?,
                None => s,
            };
            let sim = super::Simulator::new(&s)?;
            let white: Vec<f32> = sim.white().iter().map(|w| *w as f32).collect();
            check_optics_with(&s, &white, blob)?;
            Ok(Self { sim: Some(sim), note })
        };
        match named.spec {
            "analytic" => {
                anyhow::ensure!(
                    named.first_line == 0 && named.surface.is_none(),
                    "the analytic scene is a pattern of readings, with no lines in time or surface to choose: \
                     name a scene TOML file (or `patent`)"
                );
                Ok(Self { sim: None, note: None })
            }
            "patent" => simulated(patent_scene(pixels), None),
            path => {
                let whole =
                    super::Scene::load(std::path::Path::new(path)).with_context(|| format!("loading scene {path}"))?;
                let s = whole.for_device(pixels)?;
                let note = (s.instrument.sensor.pixels != whole.instrument.sensor.pixels).then(|| {
                    format!("scene {path} has {} pixels; the device reads {}", whole.instrument.sensor.pixels, s.name)
                });
                simulated(s, note)
            }
        }
    }

    /// Raw frames of scene lines `first..first + lines` (the analytic
    /// pattern: `lines` lines of it, from `blob`).
    pub fn frames(
        &self,
        blob: &BlobView<'_>,
        first: u64,
        lines: usize,
        full_scale: u16,
    ) -> anyhow::Result<SceneFrames> {
        match &self.sim {
            Some(sim) => frames_of(sim, first, lines),
            None => Ok(analytic_scene(blob, lines, full_scale)),
        }
    }
}

/// Frames for a simulated device from a scene named on the command line
/// ([`PreparedScene`]), lines from `named.first_line` on; with a note for
/// the user when the device reads a cut of the scene's line.
pub fn named_scene_frames(
    named: NamedScene<'_>,
    blob: &BlobView<'_>,
    lines: usize,
    full_scale: u16,
) -> anyhow::Result<(SceneFrames, Option<String>)> {
    let scene = PreparedScene::new(named, blob)?;
    let frames = scene.frames(blob, named.first_line, lines, full_scale)?;
    Ok((frames, scene.note))
}

/// Largest relative difference between a calibration's white reference and
/// a scene's that still counts as the same optics, once each LED's level is
/// taken out (the white reference is rounded to f32).
pub const SAME_OPTICS_TOLERANCE: f64 = 0.02;

/// Refuses a scene whose optics are not the ones `blob` was trained for:
/// the white reference (every pixel's reading of a perfect diffuser under
/// every LED) is the optics' fingerprint, so a calibration for other LEDs
/// or another cut of the line differs there. Each LED's level may differ
/// by a common factor within [`brdf_meter::blob::WHITE_RATIO_RANGE`]: a
/// calibration standardised on a white tile (host-tools `standardise`)
/// rescaled it for LEDs that drifted, or a gain changed, and is still for
/// these optics; its pixels' profile under the LED is not. The error says
/// where and what to do.
pub fn check_optics(scene: &super::Scene, blob: &BlobView<'_>) -> anyhow::Result<()> {
    check_optics_with(scene, &super::white_reference(scene)?, blob)
}

/// [`check_optics`] with the scene's white reference already simulated.
fn check_optics_with(scene: &super::Scene, white: &[f32], blob: &BlobView<'_>) -> anyhow::Result<()> {
    let d = blob.dims();
    let (p, m) = (scene.instrument.pixels(), scene.instrument.m());
    anyhow::ensure!(
        p == d.pixels && m == d.m,
        "scene `{}` has {p} pixels and {m} LEDs, the calibration {} and {}: it was trained for other optics; \
         train one for this scene (host-tools train --scene ...)",
        scene.name,
        d.pixels,
        d.m
    );
    let other = |why: String| {
        anyhow::anyhow!(
            "the calibration was trained for other optics than scene `{}`: {why}; its estimates of this scene would \
             mean nothing. Train a calibration for this scene (host-tools train --scene ...) and provision it",
            scene.name
        )
    };
    let (lo, hi) = brdf_meter::blob::WHITE_RATIO_RANGE;
    for i in 0..m {
        let ratio = |px: usize| f64::from(blob.white(px, i)) / f64::from(white[px * m + i]);
        let mut level: Vec<f64> = (0..p).map(ratio).collect();
        level.sort_by(f64::total_cmp);
        let level = level[p / 2];
        if !(level >= f64::from(lo) && level <= f64::from(hi)) {
            return Err(other(format!(
                "under LED {i} its white reference is {level:.3} times the scene's (a standardisation moves it by \
                 {lo} to {hi} times)"
            )));
        }
        for px in 0..p {
            let (w, b) = (f64::from(white[px * m + i]) * level, f64::from(blob.white(px, i)));
            if (w - b).abs() > SAME_OPTICS_TOLERANCE * w.abs().max(b.abs()) {
                return Err(other(format!(
                    "at pixel {px}, LED {i} its white reference is {b:.1} counts, the scene's {w:.1} (at the \
                     calibration's level for that LED, {level:.3} times the scene's)"
                )));
            }
        }
    }
    Ok(())
}
