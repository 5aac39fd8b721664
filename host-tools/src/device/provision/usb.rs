//! Provisioning over the device link (USB CDC-ACM on the board, TCP serial
//! on the QEMU instrument): the blob is checked against the device's sizes
//! first, so a mismatch is named here rather than refused by the device.
use crate::device::link::{Client, Transport};
use anyhow::{Context, bail};
use brdf_meter::protocol::CalInfo;

/// Sends the signed calibration `blob` (named `name` in messages; its
/// signature is checked here first and again by the device) to the device behind `c`,
/// reporting `progress(done, total)` in bytes. The device verifies it whole
/// before it replaces the active calibration; on any failure it keeps the
/// one it had.
pub fn provision<T: Transport>(
    c: &mut Client<T>,
    blob: &[u8],
    name: &str,
    progress: impl FnMut(usize, usize),
) -> anyhow::Result<CalInfo> {
    let d = super::parse_signed(blob, name)?.dims();
    let info = c.info().context("asking the device for its sizes")?;
    if (d.n, d.m, d.pixels) != (info.bins as usize, info.leds as usize, info.pixels as usize) {
        bail!(
            "{name} was made for n = {}, m = {}, P = {} but the device is n = {}, m = {}, P = {}: train for this device (`host-tools train --pixels {p}`, or with a scene `train --scene SCENE --device-pixels {p}`)",
            d.n,
            d.m,
            d.pixels,
            info.bins,
            info.leds,
            info.pixels,
            p = info.pixels
        );
    }
    if blob.len() > info.max_blob as usize {
        bail!("{name} is {} bytes; the device's slots hold {} (use fewer zones)", blob.len(), info.max_blob);
    }
    c.provision(blob, progress).context("provisioning (the device keeps its previous calibration)")
}
