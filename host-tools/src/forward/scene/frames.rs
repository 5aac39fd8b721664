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
    (0..lines as u64).map(|l| super::raw_frames(scene, l)).collect()
}

/// Frames for a simulated device from a scene named on the command line:
/// `analytic` ([`analytic_scene`]), `patent` ([`patent_scene`]) or a scene
/// TOML file, simulated for the calibration's pixel count.
pub fn named_scene_frames(
    spec: &str,
    blob: &BlobView<'_>,
    lines: usize,
    full_scale: u16,
) -> anyhow::Result<SceneFrames> {
    use anyhow::Context;
    let pixels = blob.dims().pixels;
    Ok(match spec {
        "analytic" => analytic_scene(blob, lines, full_scale),
        "patent" => {
            let s = patent_scene(pixels);
            check_optics(&s, blob)?;
            scene_frames(&s, lines)?
        }
        path => {
            let whole =
                super::Scene::load(std::path::Path::new(path)).with_context(|| format!("loading scene {path}"))?;
            let s = whole.for_device(pixels)?;
            if s.instrument.sensor.pixels != whole.instrument.sensor.pixels {
                eprintln!(
                    "note: scene {path} has {} pixels; the device reads {}",
                    whole.instrument.sensor.pixels, s.name
                );
            }
            check_optics(&s, blob)?;
            scene_frames(&s, lines)?
        }
    })
}

/// Largest relative difference between a calibration's white reference and
/// a scene's that still counts as the same optics (the white reference is
/// rounded to f32 and the scene's gain may be trimmed).
pub const SAME_OPTICS_TOLERANCE: f64 = 0.02;

/// Refuses a scene whose optics are not the ones `blob` was trained for:
/// the white reference (every pixel's reading of a perfect diffuser under
/// every LED) is the optics' fingerprint, so a calibration for other LEDs,
/// another gain or another cut of the line differs there. The error says
/// where and what to do.
pub fn check_optics(scene: &super::Scene, blob: &BlobView<'_>) -> anyhow::Result<()> {
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
    let white = super::white_reference(scene)?;
    for px in 0..p {
        for i in 0..m {
            let (w, b) = (f64::from(white[px * m + i]), f64::from(blob.white(px, i)));
            if (w - b).abs() > SAME_OPTICS_TOLERANCE * w.abs().max(b.abs()) {
                anyhow::bail!(
                    "the calibration was trained for other optics than scene `{}`: at pixel {px}, LED {i} its white \
                     reference is {b:.1} counts, the scene's {w:.1}; its estimates of this scene would mean nothing. \
                     Train a calibration for this scene (host-tools train --scene ...) and provision it",
                    scene.name
                );
            }
        }
    }
    Ok(())
}
