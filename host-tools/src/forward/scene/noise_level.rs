//! The measurement noise a scene implies, as training models it: one
//! relative level (standard deviation / value) for a perfect diffuser.
use super::{EffectSpec, NoiseModel, Scene, white_reference};

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
