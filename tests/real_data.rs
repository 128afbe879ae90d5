//! Real textures from `../shared/data` (beside the project; CI has it). The
//! sets' normal maps were baked by their authors, not fitted, so they are no
//! pixel reference: the check is that directions agree: the fitted map's red
//! and green correlate positively with theirs for the matching convention,
//! and green correlates negatively for the other one.

use std::path::{Path, PathBuf};

use normalfit::io::{ReadOptions, read_path};
use normalfit::{Convention, Options, Strength};

fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!("SKIPPED: {} is absent, so the real-texture checks did not run", dir.display());
        None
    }
}

/// Pearson correlation of two equally long series.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

/// (red, green) correlations of normals fitted from `height` with the
/// set's own normal map `normal`, under `convention`.
fn agreement(height: &Path, normal: &Path, convention: Convention) -> (f64, f64) {
    let opts = ReadOptions::default();
    let raster = read_path(height, &opts).unwrap_or_else(|e| panic!("{}: {e}", height.display()));
    let (w, h) = (raster.width, raster.height);
    let heights = raster.into_heights(None).unwrap();
    // Relief keeps slopes comparable across the sets' resolutions.
    let fit = Options::new().with_patch(5).with_convention(convention).with_strength(Strength::Relief(0.05));
    let mut ours = vec![[0.0f32; 3]; w * h];
    heights.normals_into(w, h, &fit, &mut ours).unwrap();
    let theirs = read_path(normal, &opts).unwrap();
    assert_eq!((theirs.width, theirs.height), (w, h), "{}", normal.display());
    let channel = |name: &str| -> Vec<f64> {
        theirs.plane(name).unwrap().data.to_f32().unwrap().iter().map(|&c| 2.0 * c as f64 - 1.0).collect()
    };
    let ours_c = |c: usize| -> Vec<f64> { ours.iter().map(|n| n[c] as f64).collect() };
    (correlation(&ours_c(0), &channel("R")), correlation(&ours_c(1), &channel("G")))
}

#[test]
fn fitted_normals_agree_in_direction_with_the_sets_own() {
    let Some(data) = data_dir() else { return };
    let t = data.join("tileable");
    let sets = [
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
    for (height, normal, convention) in sets {
        let other = match convention {
            Convention::OpenGl => Convention::DirectX,
            Convention::DirectX => Convention::OpenGl,
        };
        let (red, green) = agreement(&t.join(height), &t.join(normal), convention);
        let (_, green_other) = agreement(&t.join(height), &t.join(normal), other);
        eprintln!("{normal}: red {red:.3}, green {green:.3}, green with the other convention {green_other:.3}");
        assert!(red > 0.3, "{normal}: red correlation {red:.3}");
        assert!(green > 0.3, "{normal}: green correlation {green:.3}");
        assert!(green_other < -0.3, "{normal}: green correlation for the other convention {green_other:.3}");
    }
}
