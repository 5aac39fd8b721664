//! The options that load a scene into a simulated device before it is read
//! (`measure`, `standardise`): which scene, how many of its lines, from
//! which line on, and on which surface.
use crate::device::link::{Client, Transport};
use crate::forward::scene::frames::{NamedScene, PreparedScene};
use anyhow::{Context, bail};
use brdf_meter::blob::BlobView;
use brdf_meter::protocol::DeviceInfo;

/// A scene for a simulated device.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SimSceneArgs {
    /// Simulated devices only: load a scene first: `patent` (host-tools' scene
    /// simulator, patent profile), `analytic` (a simple synthetic pattern) or
    /// a scene TOML file.
    #[arg(long, value_name = "patent|analytic|PATH")]
    pub scene: Option<String>,
    /// Scene lines to load, 1..=4; the device cycles through them, so line k
    /// of the measurement sees scene line k mod this. Default: the lines
    /// read, at most 4, so they are distinct draws of the scene (its noise,
    /// its position along the surface).
    #[arg(long, value_name = "N", requires = "scene")]
    pub scene_lines: Option<usize>,
    /// The first scene line loaded: the time since calibration (the LEDs'
    /// drift, when the scene lists it) and the noise draw.
    #[arg(long, value_name = "LINE", default_value_t = 0, requires = "scene")]
    pub scene_line: u64,
    /// Another surface under the scene's instrument and effects, written as
    /// a scene's `surface.brdf`, e.g. '{ model = "lambertian", rho = 0.99 }'
    /// (a white tile).
    #[arg(long, value_name = "BRDF", requires = "scene")]
    pub scene_surface: Option<String>,
}

impl SimSceneArgs {
    /// Loads the scene, if one is named, into the device `c` (`info`)
    /// running the calibration `view`, for a reading of `read` lines.
    pub fn load<T: Transport>(
        &self,
        c: &mut Client<T>,
        info: &DeviceInfo,
        view: &BlobView<'_>,
        read: u32,
    ) -> anyhow::Result<()> {
        let Some(scene) = self.prepare(info, view)? else { return Ok(()) };
        if let Some(note) = &scene.note {
            eprintln!("note: {note}");
        }
        load_lines(c, &scene, info, view, self.scene_line, self.lines(read)?)
    }

    /// The named scene, loaded, checked and simulated once (`None` when no
    /// scene is named): give it to [`load_lines`] batch by batch.
    pub fn prepare(&self, info: &DeviceInfo, view: &BlobView<'_>) -> anyhow::Result<Option<PreparedScene>> {
        let Some(spec) = &self.scene else { return Ok(None) };
        if !info.simulated {
            bail!("--scene is for simulated devices (QEMU); this device has a real sensor");
        }
        let named = NamedScene { spec, first_line: self.scene_line, surface: self.scene_surface.as_deref() };
        Ok(Some(PreparedScene::new(named, view)?))
    }

    /// How many scene lines to load: `--scene-lines`, or by default one per
    /// line read up to what the simulated sensor holds, so that a reading of
    /// a few lines sees as many draws of the scene and not one line repeated.
    pub fn lines(&self, read: u32) -> anyhow::Result<usize> {
        let held = brdf_meter::shape::qemu::FRAME_LINES;
        let n = self.scene_lines.unwrap_or_else(|| (read as usize).min(held));
        if !(1..=held).contains(&n) {
            bail!("--scene-lines {n}: the simulated sensor holds 1 to {held} lines");
        }
        Ok(n)
    }
}

/// Loads scene lines `first..first + lines` of `scene` (at most what the
/// simulated sensor holds) into the device: for a reading of more distinct
/// lines than the sensor holds, a batch at a time.
pub fn load_lines<T: Transport>(
    c: &mut Client<T>,
    scene: &PreparedScene,
    info: &DeviceInfo,
    view: &BlobView<'_>,
    first: u64,
    lines: usize,
) -> anyhow::Result<()> {
    let frames = scene.frames(view, first, lines, info.full_scale)?;
    c.load_scene(&frames).context("loading the scene into the simulated sensor")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_lines_default_to_the_lines_read_up_to_what_the_sensor_holds() {
        let with = |n| SimSceneArgs { scene_lines: n, ..Default::default() };
        assert_eq!(with(None).lines(1).unwrap(), 1);
        assert_eq!(with(None).lines(3).unwrap(), 3);
        assert_eq!(with(None).lines(200).unwrap(), brdf_meter::shape::qemu::FRAME_LINES);
        assert_eq!(with(Some(1)).lines(4).unwrap(), 1);
        for bad in [0, brdf_meter::shape::qemu::FRAME_LINES + 1] {
            let e = with(Some(bad)).lines(4).unwrap_err().to_string();
            assert!(e.contains(&format!("--scene-lines {bad}")), "{e}");
        }
    }
}
