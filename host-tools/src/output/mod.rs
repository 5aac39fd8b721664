//! What the host writes and reads as files: atomic writes (`io`), the
//! point schema `measure` and `estimate` write (`points`, with the specular
//! peak it reports, `peak`), plots (`plot`), the TOML/CSV description
//! parsing helpers (`config`), the standard BRDF files (`bird`,
//! `astm_e1392`, on `profile`), and progress on a terminal (`progress`).
pub mod astm_e1392;
pub mod bird;
pub mod config;
pub mod io;
pub mod peak;
pub mod plot;
pub mod points;
pub mod profile;
pub mod progress;
