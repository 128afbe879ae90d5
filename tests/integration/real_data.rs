//! Real textures from `../shared/data` (beside the project; CI has it). The
//! sets' normal maps were baked by their authors, not fitted, so they are no
//! pixel reference: the check is that directions agree: the fitted map's red
//! and green correlate positively with theirs for the matching convention,
//! by a margin. The other convention is checked on its own: its encoded
//! green is 255 minus the matching one's, texel by texel, and red and blue
//! are the same.
//!
//! The tests are ignored by a plain `cargo test` (the data lives outside the
//! repository) and run by `cargo test -- --include-ignored`, the README's
//! and CI's command; there, absent data is a failure.

use std::path::Path;

use normalfit::io::{ReadOptions, read_path};
use normalfit::{Convention, FitRequest, Options, Strength};

use crate::common::shared_data;
use shared_data::{correlation, data_dir};

/// The fit's options for the real textures under `convention`.
fn fit_options(convention: Convention) -> Options {
    // Relief keeps slopes comparable across the sets' resolutions.
    Options::new().with_patch(5).with_convention(convention).with_strength(Strength::Relief(0.05))
}

/// (red, green) correlations of normals fitted from `height` with the
/// set's own normal map `normal`, under `convention`.
fn agreement(height: &Path, normal: &Path, convention: Convention) -> (f64, f64) {
    let opts = ReadOptions::default();
    let raster = read_path(height, &opts).unwrap_or_else(|e| panic!("{}: {e}", height.display()));
    let (w, h) = (raster.width, raster.height);
    let heights = raster.into_heights(None).unwrap();
    let mut ours = vec![[0.0f32; 3]; w * h];
    FitRequest::new(&fit_options(convention)).normals_into(&heights, w, h, &mut ours).unwrap();
    let theirs = read_path(normal, &opts).unwrap();
    assert_eq!((theirs.width, theirs.height), (w, h), "{}", normal.display());
    let channel = |name: &str| -> Vec<f64> {
        theirs.plane(name).unwrap().data.to_f32().unwrap().iter().map(|&c| 2.0 * c as f64 - 1.0).collect()
    };
    let ours_c = |c: usize| -> Vec<f64> { ours.iter().map(|n| n[c] as f64).collect() };
    (correlation(&ours_c(0), &channel("R")), correlation(&ours_c(1), &channel("G")))
}

/// The sets: height map, the set's own normal map, the convention it was
/// baked for.
const SETS: [(&str, &str, Convention); 5] = [
    (
        "ambientcg_Bricks061/Bricks061_1K-JPG_Displacement.jpg",
        "ambientcg_Bricks061/Bricks061_1K-JPG_NormalGL.jpg",
        Convention::OpenGl,
    ),
    (
        "ambientcg_Bricks061/Bricks061_1K-JPG_Displacement.jpg",
        "ambientcg_Bricks061/Bricks061_1K-JPG_NormalDX.jpg",
        Convention::DirectX,
    ),
    (
        "polyhaven_denim_fabric/denim_fabric_disp_1k.png",
        "polyhaven_denim_fabric/denim_fabric_nor_gl_1k.png",
        Convention::OpenGl,
    ),
    (
        "materialx_adsk_bricks_02/bricks_02_height_2k_raw.exr",
        "materialx_adsk_bricks_02/bricks_02_normal_2k_raw.exr",
        Convention::OpenGl,
    ),
    (
        "materialx_adsk_bricks_02/bricks_02_height_2k_raw.exr",
        "materialx_adsk_bricks_02/bricks_02_normal_2k_raw.png",
        Convention::OpenGl,
    ),
];

#[test]
#[ignore = "needs ../shared/data (the shared real textures); CI runs it with --include-ignored"]
fn fitted_normals_agree_in_direction_with_the_sets_own() {
    let t = data_dir().join("tileable");
    for (height, normal, convention) in SETS {
        let (red, green) = agreement(&t.join(height), &t.join(normal), convention);
        eprintln!("{normal}: red {red:.3}, green {green:.3}");
        assert!(red > 0.3, "{normal}: red correlation {red:.3}");
        assert!(green > 0.3, "{normal}: green correlation {green:.3}");
    }
}

/// DirectX's green is OpenGL's mirrored (SPEC section 2: σ = +1 instead of
/// −1), so, encoded in 8 bits, DirectX green is 255 minus OpenGL green up
/// to the rounding of each (±1), and red and blue are the same.
#[test]
#[ignore = "needs ../shared/data (the shared real textures); CI runs it with --include-ignored"]
fn the_other_convention_mirrors_green_texel_by_texel() {
    let t = data_dir().join("tileable");
    let heights = [SETS[0].0, SETS[2].0, SETS[3].0];
    for height in heights {
        let path = t.join(height);
        let raster = read_path(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (w, h) = (raster.width, raster.height);
        let samples = raster.into_heights(None).unwrap();
        let encoded = |convention| {
            let mut rgb = vec![[0u8; 3]; w * h];
            FitRequest::new(&fit_options(convention)).normals_into(&samples, w, h, &mut rgb).unwrap();
            rgb
        };
        let (gl, dx) = (encoded(Convention::OpenGl), encoded(Convention::DirectX));
        let mut tilted = 0;
        for (k, (g, d)) in gl.iter().zip(&dx).enumerate() {
            let at = (k % w, k / w);
            assert_eq!((g[0], g[2]), (d[0], d[2]), "{height} at {at:?}: red and blue, OpenGL {g:?} DirectX {d:?}");
            let sum = i32::from(g[1]) + i32::from(d[1]);
            assert!((sum - 255).abs() <= 1, "{height} at {at:?}: green, OpenGL {g:?} DirectX {d:?}");
            tilted += usize::from(g[1].abs_diff(128) > 8);
        }
        // A texture whose greens all sat at mid-grey would prove nothing.
        assert!(tilted > w * h / 10, "{height}: only {tilted} texels lean up or down");
    }
}
