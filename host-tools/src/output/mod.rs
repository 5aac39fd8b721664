//! What the host writes and reads as files: atomic writes (`io`), plots
//! (`plot`), the TOML/CSV description parsing helpers (`config`), the
//! standard BRDF files (`bird`, `astm_e1392`, on `profile`), and progress
//! on a terminal (`progress`).
pub mod astm_e1392;
pub mod bird;
pub mod config;
pub mod io;
pub mod plot;
pub mod profile;
pub mod progress;
