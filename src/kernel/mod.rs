//! The estimator kernels: `rho = W v`, one matrix-vector product per point,
//! in the forms the device runs and the host reproduces bit for bit.
//!
//! - [`f32`]: the f32 kernel (what the firmware runs per point; Cortex-M4F
//!   assembly for m = 7), on nalgebra's fixed-size types and on slices.
//! - [`q15`]: the fixed-point (Q15) kernel, its quantisation and error bound.
//! - [`cluster`]: the clustered estimator's choice of matrix per point.
//!
//! Every form keeps a fixed accumulation order so host and device agree to the
//! bit; the module docs of each say how.
pub mod cluster;
pub mod f32;
pub mod q15;
pub mod scale_free;

pub use self::cluster::select_cluster;
pub use self::f32::{mat_vec_f32, mat_vec_f32_4, mat_vec_f32_into, mat_vec_f32_slice};
pub use self::q15::*;
