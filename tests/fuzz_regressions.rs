//! Inputs the fuzzers (`fuzz/`) found, each fed through the path it broke,
//! asserting the clean result. The files in `tests/data/fuzz/` are the
//! minimised cases (`cargo fuzz tmin`), as the fuzzers wrote them.

use normalfit::io::{Raster, ReadOptions, decode};
use normalfit::tiling::{HeightSeams, KindChoice, TilingOptions, TilingReport, check};
use normalfit::{Border, Borders, Options, normals_into};

/// The fuzzers' limit: small, so a case never costs much.
const READ: ReadOptions = ReadOptions { max_texels: 1 << 20 };

fn case(name: &str) -> Vec<u8> {
    let path = format!("{}/tests/data/fuzz/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `decode_fit`'s path: bytes → raster → heights → normals, f32 and 8-bit.
/// Returns the first error; on success checks every normal.
fn decode_fit(bytes: &[u8], opts: &Options) -> normalfit::Result<()> {
    let raster = decode(bytes, &READ)?;
    let (w, h) = (raster.width, raster.height);
    let heights = raster.into_heights(None)?;
    let mut n = vec![[0.0f32; 3]; w * h];
    normals_into(&heights, w, h, opts, &mut n)?;
    for v in &n {
        let len = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!(v.iter().all(|c| c.is_finite()) && (len - 1.0).abs() <= 1e-4 && v[2] >= 0.0, "bad normal {v:?}");
    }
    let mut rgb = vec![[0u8; 3]; w * h];
    normals_into(&heights, w, h, opts, &mut rgb)
}

fn assert_finite(r: &TilingReport) {
    for axis in [r.x, r.y] {
        assert!(axis.score.is_finite() && axis.score > 0.0, "score {} in {r:?}", axis.score);
    }
}

/// `tiling`'s path: every plane, the kind detected; then the heights whole
/// and streamed row by row.
fn tiling_reports(raster: &Raster) -> [TilingReport; 3] {
    let (w, h) = (raster.width, raster.height);
    let planes: Vec<&[f32]> = raster.planes.iter().map(|p| p.data.as_slice()).collect();
    let all = check(&planes, w, h, &TilingOptions::new());
    let heights = raster.heights(None).expect("finite heights");
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let whole = check(&[&heights], w, h, &opts);
    let mut seams = HeightSeams::new(w, h);
    heights.chunks_exact(w).for_each(|row| seams.push_row(row));
    [all, whole, seams.finish(&opts)]
}

/// exr's B44 decoder computes in u16 arithmetic that wraps (as OpenEXR's
/// C code does). With overflow checks, as in test and dev builds, that
/// wrap panicked in exr's decoder thread and rayon aborted the whole
/// process; the root Cargo.toml now builds exr without them. The wrapped
/// values are ordinary halves: the file converts and is checked.
#[test]
fn exr_b44_block_whose_arithmetic_wraps_decodes() {
    let bytes = case("exr-b44-wrap.exr");
    let raster = decode(&bytes, &READ).expect("the B44 blocks decode");
    assert_eq!((raster.width, raster.height), (8, 6));
    for r in tiling_reports(&raster) {
        assert_finite(&r);
    }
    for opts in [Options::new(), Options::new().with_patch(5).with_borders(Borders::both(Border::Mirror))] {
        decode_fit(&bytes, &opts).expect("the decoded heights fit");
    }
}
