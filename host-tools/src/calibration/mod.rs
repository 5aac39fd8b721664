//! Calibration: the estimators (W from H, the prior and the noise model) and
//! training (one W per zone, the f32 gate, the gloss readings' rows and the
//! calibration on the gloss standard, the blob) and signing (key files,
//! the signed calibration), the calibration's peak resolution (what
//! the device's rule, `crate::device::reference`, makes of the black
//! glass) and the factors on its peaks' uncertainties; `families`: the rule
//! those factors, the gloss readings', the per-bin band and the
//! out-of-prior flag's threshold share (each family of held-out samples
//! covered on its own); `standardise`: the white reference made true again
//! on a certified white tile (the LEDs' drift since calibration);
//! `standardise_gloss`: the gloss scale made true on a certified black-glass
//! standard (the instrument's own error of its gloss scale); `verify_gloss`:
//! whether it reads another certified gloss standard within what both
//! state (the normalised error E_n). Consumes the forward model; knows nothing of the device link or
//! of evaluation.
pub mod demo;
pub mod estimators;
pub mod f32_gate;
pub mod families;
pub mod gloss_rows;
pub mod peak_factors;
pub mod peak_resolution;
pub mod signing;
pub mod standardise;
pub mod standardise_gloss;
pub mod train;
pub mod verify_gloss;
