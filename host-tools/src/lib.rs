//! Host tools for the BRDF meter.
