//! The measurement noise a scene implies, as training models it: per pixel
//! the variance model of its white-calibrated readings
//! ([`reading_noise`], `crate::forward::reading_noise`), and one relative
//! level (standard deviation / value) for a perfect diffuser
//! ([`relative_noise_level`], what a blob records).
use super::{EffectSpec, NoiseModel, Scene, Simulator, white_reference};
use crate::forward::reading_noise::ReadingNoise;

/// Per pixel, the variance model of its readings under the scene's sensor
/// effects: `noise` (additive, proportional, or shot + read noise on the
/// signal plus the dark level) and `quantisation` (a uniform error of one
/// step, variance step^2 / 12), each on the LED frame and again on the
/// dark frame it is corrected by, divided by the pixel's white count for
/// the LED. A scene without either trains noise-free (all zeros).
pub fn reading_noise(scene: &Scene, sim: &Simulator) -> Vec<ReadingNoise> {
    let (m, p) = (sim.m(), sim.pixels());
    let q = scene.effects.iter().find_map(|e| match e {
        EffectSpec::Quantisation { step_counts } => Some(step_counts * step_counts / 12.0),
        _ => None,
    });
    let q = q.unwrap_or(0.0);
    (0..p)
        .map(|px| {
            let d = sim.dark()[px];
            let mut r = ReadingNoise { a: 0.0, b: vec![0.0; m], c: vec![0.0; m] };
            for k in 0..m {
                let w = sim.white()[px * m + k];
                let w2 = w * w;
                // Frame variance as a function of its counts x: s2 x^2 + s1 x + s0.
                let (s2, s1, s0) = match scene.noise() {
                    Some(EffectSpec::Noise {
                        model,
                        sigma,
                        sigma_counts,
                        electrons_per_count,
                        read_sigma_counts,
                        ..
                    }) => match model {
                        NoiseModel::Proportional => (sigma.unwrap_or(0.0).powi(2), 0.0, 0.0),
                        NoiseModel::Additive => (0.0, 0.0, sigma_counts.unwrap_or(0.0).powi(2)),
                        NoiseModel::ShotRead => (
                            0.0,
                            1.0 / electrons_per_count.unwrap_or(f64::INFINITY),
                            read_sigma_counts.unwrap_or(0.0).powi(2),
                        ),
                    },
                    _ => (0.0, 0.0, 0.0),
                };
                // lit = v w + d and the dark frame d: var(v) = (var(lit) + var(dark)) / w^2.
                r.a = s2;
                r.b[k] = (2.0 * s2 * d * w + s1 * w) / w2;
                r.c[k] = (2.0 * (s2 * d * d + s1 * d + s0 + q)) / w2;
            }
            r
        })
        .collect()
}

/// The relative noise level a scene's `noise` effect implies for a perfect
/// diffuser's reading (the white level, where calibrated readings are 1):
/// proportional noise is its sigma; additive noise sigma_counts / white;
/// shot + read noise sqrt(white / e_per_count + read^2) / white, with the
/// median white count over pixels and LEDs. A scene without noise trains
/// noise-free: the estimator models what the scene says and no more.
pub fn relative_noise_level(scene: &Scene) -> anyhow::Result<f64> {
    let Some(EffectSpec::Noise { model, sigma, sigma_counts, electrons_per_count, read_sigma_counts, .. }) =
        scene.noise()
    else {
        return Ok(0.0);
    };
    let white = || -> anyhow::Result<f64> {
        let mut w: Vec<f32> = white_reference(scene)?;
        w.sort_by(f32::total_cmp);
        Ok(w[w.len() / 2] as f64)
    };
    Ok(match model {
        NoiseModel::Proportional => sigma.unwrap_or(0.0),
        NoiseModel::Additive => sigma_counts.unwrap_or(0.0) / white()?,
        NoiseModel::ShotRead => {
            let w = white()?;
            let e = electrons_per_count.unwrap_or(f64::INFINITY);
            let r = read_sigma_counts.unwrap_or(0.0);
            (w / e + r * r).sqrt() / w
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn scene_noise_follows_the_scenes_noise_effect() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let load = |f: &str| Scene::load(&dir.join(f)).unwrap();
        assert_eq!(relative_noise_level(&load("patent-profile.toml")).unwrap(), 0.02);
        assert_eq!(relative_noise_level(&load("far-field.toml")).unwrap(), 0.0);
        assert_eq!(relative_noise_level(&load("hard/noise-0.2.toml")).unwrap(), 0.2);
        let handheld = relative_noise_level(&load("handheld.toml")).unwrap();
        assert!(handheld > 0.0 && handheld < 0.2, "{handheld}");
    }
}
