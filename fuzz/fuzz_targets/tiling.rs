//! Bytes → `decode` → `tiling::check`, as `normalfit tiling` does, and the
//! same heights through `HeightSeams` row by row, as `normalfit convert
//! --border auto` does while it streams.
//!
//! Must hold for any bytes: no panic; scores finite and positive, verdicts
//! the score against the threshold (the documented `AxisReport::score`);
//! and `HeightSeams` gives `check`'s report of the same heights, whole or
//! cut short after any number of rows (its documented promise).
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::tiling::{HeightSeams, KindChoice, TilingOptions, check};
use normalfit_fuzz::{Case, assert_report, assert_same_report, check_heights, decoded};

fuzz_target!(|data: &[u8]| {
    let case = Case::of(data);
    let Some(raster) = decoded(data) else { return };
    let (w, h) = (raster.width, raster.height);

    // Every plane, the kind detected or forced.
    let opts = TilingOptions::new().with_kind(case.kind);
    let planes: Vec<Vec<f32>> = raster.planes.iter().map(|p| p.data.to_f32().expect("memory")).collect();
    let planes: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
    assert_report(&check(&planes, w, h, &opts).unwrap(), &opts);

    // The height alone, whole and streamed.
    let Some(heights) = check_heights(raster.heights(case.channel.clone()), w * h) else { return };
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let whole = check(&[&heights], w, h, &opts).unwrap();
    assert_report(&whole, &opts);
    let mut seams = HeightSeams::new(w, h).unwrap();
    for row in heights.chunks_exact(w) {
        seams.push_row(row).unwrap();
    }
    assert_eq!(seams.rows(), h);
    assert_same_report(&whole, &seams.finish(&opts), &opts);

    // A stream cut short: the report of the rows pushed.
    let rows = (h * (usize::from(case.fraction) + 1)).div_ceil(256).clamp(1, h);
    let mut seams = HeightSeams::new(w, h).unwrap();
    for row in heights.chunks_exact(w).take(rows) {
        seams.push_row(row).unwrap();
    }
    let part = check(&[&heights[..rows * w]], w, rows, &opts).unwrap();
    assert_same_report(&part, &seams.finish(&opts), &opts);
});
