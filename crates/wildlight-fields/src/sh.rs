//! Real spherical harmonics of a unit direction (degrees 0…3, i.e. 1, 4, 9 or
//! 16 coefficients), in the usual graphics ordering `Y_l^m`, m = −l…l,
//! orthonormal on the sphere. Used to encode directions as extra field inputs.

use crate::real::Real;

/// Number of coefficients of `degree` bands (`degree` ∈ 1..=4 bands, i.e. l < degree).
pub fn sh_len(bands: usize) -> usize {
    bands * bands
}

/// Writes the SH basis of `d` (unit vector) for `bands` ∈ 1..=4 into `out` (`bands²` values).
pub fn sh_encode<T: Real>(d: [T; 3], bands: usize, out: &mut [T]) {
    assert!((1..=4).contains(&bands), "sh_encode: bands must be 1..=4");
    assert!(out.len() >= bands * bands);
    let c = |v: f64| T::from_f64(v);
    let [x, y, z] = d;
    out[0] = c(0.282_094_791_773_878_14);
    if bands == 1 {
        return;
    }
    out[1] = c(-0.488_602_511_902_919_9) * y;
    out[2] = c(0.488_602_511_902_919_9) * z;
    out[3] = c(-0.488_602_511_902_919_9) * x;
    if bands == 2 {
        return;
    }
    let (xx, yy, zz) = (x * x, y * y, z * z);
    out[4] = c(1.092_548_430_592_079_2) * x * y;
    out[5] = c(-1.092_548_430_592_079_2) * y * z;
    out[6] = c(0.315_391_565_252_520_05) * (c(3.0) * zz - T::ONE);
    out[7] = c(-1.092_548_430_592_079_2) * x * z;
    out[8] = c(0.546_274_215_296_039_6) * (xx - yy);
    if bands == 3 {
        return;
    }
    out[9] = c(-0.590_043_589_926_643_5) * y * (c(3.0) * xx - yy);
    out[10] = c(2.890_611_442_640_554) * x * y * z;
    out[11] = c(-0.457_045_799_464_465_8) * y * (c(5.0) * zz - T::ONE);
    out[12] = c(0.373_176_332_590_115_4) * z * (c(5.0) * zz - c(3.0));
    out[13] = c(-0.457_045_799_464_465_8) * x * (c(5.0) * zz - T::ONE);
    out[14] = c(1.445_305_721_320_277) * z * (xx - yy);
    out[15] = c(-0.590_043_589_926_643_5) * x * (xx - c(3.0) * yy);
}
