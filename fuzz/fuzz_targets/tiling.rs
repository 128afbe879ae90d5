//! Bytes → `decode` → `tiling::check`, as `normalfit tiling` does, and the
//! same heights through `HeightSeams` row by row, as `normalfit convert
//! --border auto` does while it streams.
//!
//! Must hold for any bytes: no panic; scores finite and positive, verdicts
//! the score against the threshold (the documented `AxisReport::score`);
//! and `HeightSeams` gives `check`'s report of the same heights, whole or
//! fed only the lines it reads (its documented promise); a stream cut
//! short is refused.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::normal_map::KindChoice;
use normalfit::tiling::{HeightSeams, TilingOptions, check};
use normalfit_fuzz::{Case, assert_report, assert_same_report, check_heights, decoded};

fuzz_target!(|data: &[u8]| {
    let case = Case::of(data);
    let Some(raster) = decoded(data) else { return };
    let (w, h) = (raster.width, raster.height);

    // Every plane, the kind detected or forced.
    let opts = TilingOptions::new().with_kind(case.kind);
    let planes: Vec<Vec<f32>> = raster.planes.iter().map(|p| p.data.to_f32().expect("memory")).collect();
    let planes: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
    match check(&planes, w, h, &opts) {
        Ok(report) => assert_report(&report, &opts),
        // A map holding a NaN or infinite sample is refused, as
        // `normalfit tiling` refuses it, and only such a map.
        Err(normalfit::Error::NonFiniteHeight { .. } | normalfit::Error::NonFiniteNormal { .. }) => {
            assert!(planes.iter().any(|p| p.iter().any(|v| !v.is_finite())));
        }
        Err(e) => panic!("{e}"),
    }

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
    assert_same_report(&whole, &seams.finish(&opts).unwrap(), &opts);

    // Only the lines the check reads: every row's edge columns, then the
    // edge rows; and a stream cut short, refused.
    let mut seams = HeightSeams::new(w, h).unwrap();
    let cols = seams.edge_columns();
    for row in heights.chunks_exact(w) {
        let kept: Vec<f32> = cols.iter().flat_map(|r| row[r.clone()].iter().copied()).collect();
        seams.push_edge_columns(&kept).unwrap();
    }
    for rows in seams.edge_rows() {
        seams.push_edge_rows(&heights[rows.start * w..rows.end * w]).unwrap();
    }
    assert_same_report(&whole, &seams.finish(&opts).unwrap(), &opts);
    let rows = (h * usize::from(case.fraction)) / 256;
    let mut seams = HeightSeams::new(w, h).unwrap();
    for row in heights.chunks_exact(w).take(rows) {
        seams.push_row(row).unwrap();
    }
    assert!(seams.finish(&opts).is_err() == (rows < h && w > 0));
});
