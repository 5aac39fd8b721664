//! What the host writes and reads as files: atomic writes (`io`), plots
//! (`plot`), and the TOML/CSV description parsing helpers (`config`).
pub mod config;
pub mod io;
pub mod plot;
pub mod progress;
pub mod profile;
pub mod bird;
pub mod astm_e1392;
