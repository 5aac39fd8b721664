//! Request handling: one request in, one reply out, synchronous. Provisioning
//! writes go straight to the flash's inactive slot; a measurement is handed to
//! the acquisition task.
use super::{Core, Job, Shared};
use crate::estimate::Calibration;
use crate::firmware::image::Target;
use crate::hw::{FrameInput, FrameLoadError, MappedFlash};
use crate::protocol::{
    BootState, DeviceError, DeviceInfo, FirmwareInfo, MAX_CHUNK, MAX_KEY_IDS, PROTOCOL_VERSION, Request, Response,
};
use core::sync::atomic::Ordering;

impl<F: MappedFlash, const N: usize, const M: usize, const P: usize> Shared<F, N, M, P> {
    /// Answers one request.
    pub fn handle<S: FrameInput>(&self, seq: u32, req: &Request<'_>, scene: &mut S) -> Response<'static> {
        let r = self.core.lock(|c| {
            let mut guard = c.borrow_mut();
            let c = &mut *guard;
            let measuring = c.status.measuring;
            let r: Result<Response<'static>, DeviceError> = match *req {
                Request::Info => Ok(Response::Info(DeviceInfo {
                    protocol: PROTOCOL_VERSION,
                    firmware: self.version,
                    bins: N as u16,
                    leds: M as u16,
                    pixels: P as u16,
                    full_scale: self.full_scale,
                    max_blob: c.store.max_blob(),
                    ram_matrix_words: c.cal.ram_words() as u32,
                    simulated: self.simulated,
                    calibration: c.cal.active().map(|a| a.info),
                })),
                Request::Status => {
                    c.status.provisioning = c.store.provisioning();
                    Ok(Response::Status(c.status))
                }
                Request::ProvisionBegin { .. } | Request::ProvisionCommit if measuring => Err(DeviceError::Busy),
                Request::ProvisionBegin { len, crc } => c
                    .store
                    .begin(len, crc)
                    .map(|slot| Response::ProvisionReady { slot, max_chunk: MAX_CHUNK as u16 })
                    .map_err(DeviceError::from),
                Request::ProvisionChunk { offset, data } => c
                    .store
                    .write_chunk(offset, data)
                    .map(|next_offset| Response::ChunkAck { next_offset })
                    .map_err(DeviceError::from),
                Request::ProvisionCommit => {
                    c.store.commit(|v| Calibration::<N, M, P>::check(v)).map_err(DeviceError::from).and_then(|_| {
                        let (info, view) = c.store.active_blob().ok_or(DeviceError::Storage)?;
                        c.cal.load(&view, info)?;
                        let cal = c.cal.active().map(|a| a.info).ok_or(DeviceError::Storage)?;
                        c.status.calibration = Some(cal);
                        Ok(Response::Committed(cal))
                    })
                }
                Request::ProvisionAbort => c.store.abort().map(|_| Response::Aborted).map_err(DeviceError::from),
                Request::Measure { .. } if measuring => Err(DeviceError::Busy),
                Request::Measure { .. } if c.cal.active().is_none() => {
                    Err(c.store.unreadable().unwrap_or(DeviceError::NoCalibration))
                }
                Request::Measure { format, .. } if !format.bin_range(N).fits(N) => {
                    Err(DeviceError::BadBins { bins: N as u16 })
                }
                Request::Measure { lines, format } => {
                    c.status.measuring = true;
                    c.inspecting = false;
                    self.stop.store(false, Ordering::SeqCst);
                    self.start.signal(Job { seq, lines, format, inspect: None });
                    Ok(Response::MeasureStarted { lines })
                }
                Request::Stop => {
                    self.stop.store(true, Ordering::SeqCst);
                    Ok(Response::StopRequested)
                }
                Request::SimFrame { line, frame, first_pixel, pixels } => {
                    if !pixels.is_whole(2) {
                        Err(DeviceError::Simulation)
                    } else {
                        scene
                            .load(line, frame, first_pixel, pixels.u16s())
                            .map(|_| Response::SimLoaded)
                            .map_err(sim_err)
                    }
                }
                Request::SimLines { lines } => scene.set_lines(lines).map(|_| Response::SimLoaded).map_err(sim_err),
                Request::FirmwareInfo => Ok(Response::Firmware(firmware_info(c, self.target, self.version))),
                Request::UpdateBegin { .. } | Request::UpdateCommit if measuring => Err(DeviceError::Busy),
                Request::UpdateBegin { len, crc } => c
                    .update(|fw| fw.begin(len, crc))
                    .map(|next_offset| Response::UpdateReady { next_offset, max_chunk: MAX_CHUNK as u16 }),
                Request::UpdateChunk { offset, data } => {
                    c.update(|fw| fw.write(offset, data)).map(|next_offset| Response::ChunkAck { next_offset })
                }
                Request::UpdateCommit => {
                    c.update(|fw| fw.commit()).map(|version| Response::UpdateCommitted { version })
                }
                Request::UpdateAbort => c.update(|fw| fw.abort()).map(|_| Response::Aborted),
                Request::Reboot => {
                    self.reboot.signal(());
                    Ok(Response::Rebooting)
                }
                Request::RecipeBegin { .. } | Request::RecipeCommit if measuring => Err(DeviceError::Busy),
                Request::RecipeBegin { .. }
                | Request::RecipeChunk { .. }
                | Request::RecipeCommit
                | Request::RecipeAbort => c.recipe_request(req),
                Request::Inspect { .. } if measuring => Err(DeviceError::Busy),
                Request::Inspect { .. } if c.cal.active().is_none() => {
                    Err(c.store.unreadable().unwrap_or(DeviceError::NoCalibration))
                }
                Request::Inspect { format, .. } if !format.bin_range(N).fits(N) => {
                    Err(DeviceError::BadBins { bins: N as u16 })
                }
                Request::Inspect { lines, defect_points, format } => c.usable_recipe().map(|view| {
                    c.recipe_view = Some(view);
                    c.status.measuring = true;
                    c.inspecting = true;
                    c.inspector = crate::inspect::Inspector::new();
                    c.reject_plan = crate::inspect::reject::Planner::new();
                    self.stop.store(false, Ordering::SeqCst);
                    let inspect = Some(super::InspectJob { defect_points });
                    self.start.signal(Job { seq, lines, format, inspect });
                    Response::MeasureStarted { lines }
                }),
                Request::InspectStatus => Ok(Response::Inspection(c.inspect_status())),
            };
            if r.is_err() {
                c.status.refused = c.status.refused.wrapping_add(1);
            }
            r
        });
        r.unwrap_or_else(Response::Error)
    }

    /// What `FirmwareInfo` answers: version, boot state, self-test, keys.
    pub fn firmware_info(&self) -> FirmwareInfo {
        self.core.lock(|c| firmware_info(&c.borrow(), self.target, self.version))
    }

    /// Counts a frame that could not be read.
    pub fn count_bad_frame(&self) {
        self.core.lock(|c| {
            let mut c = c.borrow_mut();
            c.status.bad_frames = c.status.bad_frames.wrapping_add(1);
        });
    }
}

/// What `FirmwareInfo` reports.
fn firmware_info<F, const N: usize, const M: usize, const P: usize>(
    c: &Core<F, N, M, P>,
    target: Target,
    version: [u8; 3],
) -> FirmwareInfo {
    let keys = crate::signed::TRUSTED_KEYS;
    let mut trusted = [[0u8; 8]; MAX_KEY_IDS];
    for (id, pk) in trusted.iter_mut().zip(keys) {
        *id = crate::signed::key_id(pk);
    }
    let fw = c.firmware.as_deref();
    FirmwareInfo {
        version,
        target,
        boot: fw.map_or(BootState::Unknown, |f| f.boot_state()),
        self_test: c.self_test,
        updates: fw.is_some(),
        max_image: fw.map_or(0, |f| f.max_image()),
        receiving: fw.and_then(|f| f.receiving()),
        pending: fw.and_then(|f| f.pending()),
        blob_formats: [crate::blob::FORMAT_VERSION_1, crate::blob::FORMAT_VERSION],
        trusted_count: keys.len().min(u8::MAX as usize) as u8,
        trusted,
        trusts_development_key: crate::signed::TRUSTS_DEVELOPMENT_KEY,
        refused: c.update_refused,
    }
}

fn sim_err(_: FrameLoadError) -> DeviceError {
    DeviceError::Simulation
}
