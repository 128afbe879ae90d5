//! Bytes → `decode` → heights → `normals_into`, as `normalfit convert` does
//! with an image read whole.
//!
//! Must hold for any bytes: no panic, abort, hang or huge allocation;
//! failures are `Err` with a one-line message; a raster keeps its size
//! promises; and every normal is finite, of unit length, facing up, with
//! the 8-bit output the contract's encoding of the float output.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::FitRequest;
use normalfit_fuzz::{Case, assert_unit_normal, check_heights, decoded, encode8};

fuzz_target!(|data: &[u8]| {
    let case = Case::of(data);
    let Some(raster) = decoded(data) else { return };
    let (w, h) = (raster.width, raster.height);
    let Some(heights) = check_heights(raster.into_heights(case.channel.clone()), w * h) else { return };

    let mut normals = vec![[0.0f32; 3]; w * h];
    FitRequest::new(&case.fit)
        .normals_into(&heights, w, h, &mut normals)
        .expect("finite heights and valid options must fit");
    for (k, &n) in normals.iter().enumerate() {
        assert_unit_normal(n, k);
    }

    // The same fit into 8-bit texels: the contract's rounding of the float
    // normal, give or take one where the f32 rounding of n crosses a half.
    let mut rgb = vec![[0u8; 3]; w * h];
    FitRequest::new(&case.fit).normals_into(&heights, w, h, &mut rgb).expect("the same fit into 8 bits");
    for (k, (n, c)) in normals.iter().zip(&rgb).enumerate() {
        for i in 0..3 {
            let d = (i32::from(c[i]) - encode8(n[i])).abs();
            assert!(d <= 1, "texel {k}: 8-bit {c:?} is not the encoding of {n:?}");
        }
    }
});
