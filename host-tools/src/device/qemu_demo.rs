//! The QEMU instrument's demo: a calibration trained for its simulated
//! optics (the handheld's line cut to the device's pixels, or the
//! patent-profile scene at the device's pixel count), provisioned, and a
//! 4-line scene loaded, so `measure` works at once.
use crate::calibration::demo::{scene_prior, train_for_scene, train_scale_free_for_scene, train_scene_for_slot};
use crate::device::link::{Client, SerialTransport, TcpTransport, Transport};
use crate::forward::pairs::Criterion;
use crate::forward::scene::Scene;
use crate::forward::scene::frames::{patent_scene, scene_frames};
use anyhow::Context;
use brdf_meter::protocol::CalInfo;
use std::path::Path;
use std::time::Duration;

/// Connects to the QEMU instrument's serial (a pseudo-terminal path when
/// `pty`, else TCP `HOST:PORT`) and waits until the firmware answers.
pub fn connect(addr: &str, pty: bool) -> anyhow::Result<Client<Box<dyn Transport>>> {
    let t: Box<dyn Transport> =
        if pty { Box::new(SerialTransport::open(addr)?) } else { Box::new(TcpTransport::connect(addr)?) };
    let mut c = Client::new(t)?;
    c.wait_ready(Duration::from_secs(20))?;
    Ok(c)
}

/// Which optics the demo simulates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum DemoScene {
    /// The handheld instrument (`scenes/handheld.toml`, every effect), the
    /// device's pixels cut from the centre of its line.
    #[default]
    Handheld,
    /// The patent profile's optics at every pixel (no per-pixel geometry).
    Patent,
}

impl DemoScene {
    /// The scene for a device of `pixels` pixels.
    pub fn scene(self, pixels: usize) -> anyhow::Result<Scene> {
        match self {
            Self::Handheld => {
                let path = crate::device::link::qemu::workspace_root().join("scenes/handheld.toml");
                Scene::load(&path)?.for_device(pixels)
            }
            Self::Patent => Ok(patent_scene(pixels)),
        }
    }
}

/// Which calibration the demo trains.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum DemoEstimator {
    /// Wiener (eq. 22) on the patent prior, 4 zones (the patent's).
    Wiener,
    /// Scale-free on the MERL prior with the out-of-prior flag, 4 zones.
    ScaleFree,
    /// Scale-free piecewise on the MERL prior with the flag, 1 zone, as
    /// many clusters as the QEMU build's 16 KiB slot takes: what `train`
    /// gives by default, so the demo shows the instrument as shipped.
    #[default]
    ScaleFreePiecewise,
}

/// Trains the demo calibration for the device behind `c`, signs it with the
/// DEVELOPMENT KEY (NOT FOR PRODUCTION; the QEMU firmware trusts it by
/// default), writes it to `blob_path`, provisions it and loads the scene;
/// returns the signed calibration and what the device reports for it.
pub fn set_up<T: Transport>(
    c: &mut Client<T>,
    blob_path: &Path,
    kind: DemoEstimator,
    optics: DemoScene,
) -> anyhow::Result<(Vec<u8>, CalInfo)> {
    let info = c.info()?;
    let scene = optics.scene(info.pixels as usize)?;
    let blob = match kind {
        DemoEstimator::Wiener => train_for_scene(&scene, 4, 0.02)?.blob,
        DemoEstimator::ScaleFree => train_scale_free_for_scene(&scene, 4, 0.02, false)?.blob,
        DemoEstimator::ScaleFreePiecewise => {
            // As many clusters as the device's slot takes with the signature.
            let room = (info.max_blob as usize).saturating_sub(brdf_meter::signed::TRAILER_LEN);
            // At the scene's own noise level, as `train --scene` trains by default.
            let prior = scene_prior(&scene, "merl")?;
            let noise = crate::forward::scene::noise_level::relative_noise_level(&scene)?;
            let kind = brdf_meter::blob::EstimatorKind::ScaleFreePiecewise;
            train_scene_for_slot(&scene, 1, noise, kind, &prior, Criterion::PeakRelative, room)?.blob
        }
    };
    let signed = crate::calibration::signing::sign_with_dev_key(&blob);
    crate::output::io::write_atomic(blob_path, &signed)?;
    let cal = c.provision(&signed, |_, _| {}).context("provisioning the demo calibration")?;
    c.load_scene(&scene_frames(&scene, 4)?)?;
    Ok((signed, cal))
}
