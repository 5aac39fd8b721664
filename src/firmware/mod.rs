//! Firmware updates in the field: the signed image format ([`image`]) and
//! the updater that receives one over the link into the update partition and
//! hands it to the bootloader ([`update`], on embassy-boot).
//!
//! The flash map (`memory.x`, [`crate::shape::board`]): bootloader, boot
//! state, active image, update image (DFU), recipe slots, calibration slots.
//! The bootloader (`src/bin/bootloader.rs`, embassy-boot) swaps a marked
//! update into the active region page by page, with its progress in the
//! boot state so a power cut resumes the swap; the new image runs on trial
//! and confirms itself only after its self-test (the application's
//! `SelfTest`); otherwise the next reset swaps the previous image back.
#[cfg(any(feature = "app", feature = "bootloader"))]
pub mod boot;
pub mod image;
#[cfg(feature = "app")]
pub mod update;
