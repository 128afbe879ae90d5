//! Mip chains (issue 33): each level of `mips::fit_chain` against the fit
//! of the shared reference (tests/common/reference.rs) of the heights box
//! filtered here, plainly; `average_chain` against the renormalised mean
//! written here; `mean_lengths` on a pattern whose answer is known; and the
//! chain's properties (level sizes, flat in → flat out, wrap commutes with
//! shifting).

use crate::common;

use common::mips::{box_filter, heights};
use common::reference;
use normalfit::mips::{self, MipLevel};
use normalfit::{Border, Borders, Fit, FitRequest, Options, Spacing, Strength, Units};

fn assert_close(got: &[f32; 3], want: [f64; 3], tolerance: f64, at: &str) {
    let off = (0..3).map(|c| (f64::from(got[c]) - want[c]).abs()).fold(0.0, f64::max);
    assert!(off <= tolerance, "{at}: {got:?}, want {want:?}");
}

#[test]
fn levels_are_counted_as_direct3d_and_vulkan_count_them() {
    for (w, h) in [(1, 1), (2, 1), (300, 7), (7, 300), (1024, 1024), (1000, 3), (5, 5)] {
        let sizes = mips::level_sizes(w, h);
        let longest = w.max(h) as f64;
        assert_eq!(sizes.len(), 1 + longest.log2().floor() as usize, "{w} × {h}");
        assert_eq!(sizes[0], (w, h));
        assert_eq!(*sizes.last().unwrap(), (1, 1));
        for pair in sizes.windows(2) {
            assert_eq!(pair[1], ((pair[0].0 / 2).max(1), (pair[0].1 / 2).max(1)), "{w} × {h}");
        }
    }
}

/// Every level of the fit chain is the reference fit of the heights box
/// filtered to its size, texels spaced by their footprints, with the finest
/// level's gain; level 0 is the plain fit, bit for bit. Odd and
/// non-square sizes, every border, both fits, N 3 and 5, the texel units
/// and the map's.
#[test]
fn each_level_of_the_fit_chain_is_the_fit_of_the_box_filtered_heights() {
    let cases = [
        ((32, 32), Border::Wrap, Fit::Orthogonal, 3, Units::Texels),
        ((37, 20), Border::Clamp, Fit::Orthogonal, 5, Units::Texels),
        ((30, 7), Border::Mirror, Fit::Vertical, 3, Units::Texels),
        ((24, 18), Border::Wrap, Fit::Vertical, 5, Units::Texels),
        ((21, 16), Border::Clamp, Fit::Orthogonal, 3, Units::Map(Spacing::Uniform { x: 10.0, y: 12.0 })),
    ];
    for ((w, h), border, fit, n, units) in cases {
        let samples = heights(w, h);
        let mut opts = Options::new().with_patch(n).with_fit(fit).with_borders(Borders::both(border));
        // Relief is a gain per texel width, which map units refuse: there
        // the gain is the vertical exaggeration itself.
        let strength = if matches!(units, Units::Texels) { Strength::Relief(0.4) } else { Strength::Scale(1.5) };
        opts = opts.with_strength(strength).with_units(units.clone());
        let chain = mips::fit_chain(&samples, (w, h), &opts).unwrap();
        assert_eq!(chain.iter().map(|l| (l.width, l.height)).collect::<Vec<_>>(), mips::level_sizes(w, h));

        let mut plain = vec![[0f32; 3]; w * h];
        FitRequest::new(&opts).normals_into(&samples, w, h, &mut plain).unwrap();
        assert!(chain[0].texels == plain, "level 0 is the fit, bit for bit");

        // The heights in the fit's units, and the gain of the finest level.
        let unit = if matches!(units, Units::Texels) { 1.0 / 65535.0 } else { 1.0 };
        let values: Vec<f64> = samples.iter().map(|&v| f64::from(v) * unit).collect();
        let gain = reference::gain(&opts, w);
        let (sx, sy) = reference::spacing(&opts, 0);
        for (k, level) in chain.iter().enumerate().skip(1) {
            let (lw, lh) = (level.width, level.height);
            let reduced = box_filter(&values, (w, h), (lw, lh));
            let spacing = Spacing::Uniform { x: sx * w as f64 / lw as f64, y: sy * h as f64 / lh as f64 };
            let level_opts =
                opts.clone().with_units(Units::Map(spacing)).with_strength(Strength::Scale(gain)).with_invert(false);
            for y in 0..lh {
                for x in 0..lw {
                    let want = reference::normal_at(&reduced, lw, lh, &level_opts, x, y);
                    let at = format!("{w} × {h} {border:?} {fit:?} N {n}: level {k} ({lw} × {lh}) texel ({x}, {y})");
                    assert_close(&level.texels[y * lw + x], want, 2e-6, &at);
                }
            }
        }
    }
}

/// A level's slopes keep their meaning: a ramp's normal is the same at
/// every level the ramp spans (a level of one texel across is flat).
#[test]
fn a_ramp_keeps_its_slope_down_the_chain() {
    let (w, h) = (64, 16);
    let ramp: Vec<f32> = (0..w * h).map(|k| 0.01 * (k % w) as f32 + 0.03 * (k / w) as f32).collect();
    let opts = Options::new().with_borders(Borders::both(Border::Clamp)).with_strength(Strength::Scale(2.0));
    let chain = mips::fit_chain(&ramp, (w, h), &opts).unwrap();
    let want = reference::unit([-0.02, 0.06, 1.0]);
    for (k, level) in chain.iter().enumerate() {
        if level.width < 3 || level.height < 3 {
            continue;
        }
        let centre = (level.height / 2) * level.width + level.width / 2;
        assert_close(&level.texels[centre], want, 1e-6, &format!("level {k}"));
    }
}

#[test]
fn flat_heights_give_flat_levels() {
    for border in [Border::Wrap, Border::Clamp, Border::Mirror] {
        let flat = vec![0.25f32; 45 * 13];
        let opts = Options::new().with_patch(5).with_borders(Borders::both(border));
        for level in mips::fit_chain(&flat, (45, 13), &opts).unwrap() {
            assert!(
                level.texels.iter().all(|n| *n == [0.0, 0.0, 1.0]),
                "{border:?} {} × {}",
                level.width,
                level.height
            );
        }
    }
}

/// Wrap tiles at every level: heights shifted by 8 × 4 texels give levels
/// shifted by 8 / 2^k × 4 / 2^k.
#[test]
fn wrap_commutes_with_shifting_at_every_level() {
    let (w, h) = (32, 16);
    let samples = heights(w, h);
    let shifted: Vec<u16> = (0..w * h).map(|k| samples[((k / w + 4) % h) * w + (k % w + 8) % w]).collect();
    let opts = Options::new().with_patch(5);
    let (a, b) = (mips::fit_chain(&samples, (w, h), &opts).unwrap(), mips::fit_chain(&shifted, (w, h), &opts).unwrap());
    for k in 0..3 {
        let (lw, lh, dx, dy) = (a[k].width, a[k].height, 8 >> k, 4 >> k);
        for y in 0..lh {
            for x in 0..lw {
                let want = a[k].texels[((y + dy) % lh) * lw + (x + dx) % lw].map(f64::from);
                assert_close(&b[k].texels[y * lw + x], want, 1e-6, &format!("level {k} ({x}, {y})"));
            }
        }
    }
}

/// The renormalised mean, written plainly: level k + 1 from level k, each
/// texel the area-weighted sum of the finer texels under it.
#[test]
fn each_level_of_the_average_chain_is_the_renormalised_mean_of_the_finer_one() {
    for (w, h) in [(16, 16), (30, 7), (5, 3)] {
        let normals: Vec<[f32; 3]> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                reference::unit([(x * 0.9).sin() * 0.6, (y * 0.7).cos() * 0.4, 1.0]).map(|c| c as f32)
            })
            .collect();
        let chain = mips::average_chain(&normals, (w, h)).unwrap();
        assert!(chain[0].texels == normals);
        for k in 1..chain.len() {
            let MipLevel { width: fw, height: fh, texels: finer } = &chain[k - 1];
            let (lw, lh) = (chain[k].width, chain[k].height);
            let planes: Vec<Vec<f64>> = (0..3)
                .map(|c| box_filter(&finer.iter().map(|n| f64::from(n[c])).collect::<Vec<_>>(), (*fw, *fh), (lw, lh)))
                .collect();
            for (t, got) in chain[k].texels.iter().enumerate() {
                let want = reference::unit([planes[0][t], planes[1][t], planes[2][t]]);
                assert_close(got, want, 1e-6, &format!("{w} × {h}: level {k} texel {t}"));
            }
        }
    }
}

/// Two alternating slopes, ±s along x: each pair's mean normal is
/// (0, 0, 1) / √(1 + s²) long, at every level above the finest (and a
/// level of one texel across covers as many of each).
#[test]
fn the_mean_length_of_two_alternating_slopes_is_their_cosine() {
    let s = 0.75f64;
    let (w, h) = (16, 8);
    let normals: Vec<[f32; 3]> = (0..w * h)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            reference::unit([-sign * s, 0.0, 1.0]).map(|c| c as f32)
        })
        .collect();
    let lengths = mips::mean_lengths(&normals, (w, h)).unwrap();
    assert!(lengths[0].texels.iter().all(|&l| (f64::from(l) - 1.0).abs() < 1e-6));
    let want = 1.0 / (1.0 + s * s).sqrt();
    for level in &lengths[1..] {
        for &l in &level.texels {
            assert!((f64::from(l) - want).abs() < 1e-6, "{} × {}: {l}, want {want}", level.width, level.height);
        }
    }
}

#[test]
fn wrong_sizes_are_errors() {
    assert!(mips::average_chain(&[[0.0, 0.0, 1.0]; 5], (2, 3)).is_err());
    assert!(mips::average_chain(&[], (0, 3)).is_err());
    assert!(mips::box_reduce(&[1.0; 6], (3, 2), (4, 1)).is_err());
    assert!(mips::box_reduce(&[1.0; 5], (3, 2), (1, 1)).is_err());
}

/// `mean_lengths` at every level is |n̄|, the length of the mean of the
/// finest normals under each texel: their box filter by overlap areas
/// (tests/common), from the finest level, at odd and non-square sizes
/// where a level's footprints do not nest in the level before's.
#[test]
fn mean_lengths_are_the_lengths_of_the_box_filtered_finest_normals() {
    for (w, h) in [(37, 21), (300, 7), (16, 16), (1, 5)] {
        let normals: Vec<[f32; 3]> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                reference::unit([1.2 * (x * 0.7).sin(), 0.9 * (y * 1.1 + x * 0.3).cos(), 1.0]).map(|c| c as f32)
            })
            .collect();
        let lengths = mips::mean_lengths(&normals, (w, h)).unwrap();
        assert_eq!(lengths.len(), mips::level_sizes(w, h).len());
        let planes: Vec<Vec<f64>> = (0..3).map(|c| normals.iter().map(|n| f64::from(n[c])).collect()).collect();
        for (k, level) in lengths.iter().enumerate() {
            let (lw, lh) = (level.width, level.height);
            let means: Vec<Vec<f64>> = planes.iter().map(|p| box_filter(p, (w, h), (lw, lh))).collect();
            let mut shortest = f64::MAX;
            for (t, &got) in level.texels.iter().enumerate() {
                let want = (0..3).map(|c| means[c][t] * means[c][t]).sum::<f64>().sqrt();
                let at = format!("{w} × {h}, level {k} ({lw} × {lh}) texel {t}");
                assert!((f64::from(got) - want).abs() < 1e-6, "{at}: {got}, want {want}");
                shortest = shortest.min(want);
            }
            // Not a test of ones: detail cancels out above the finest level.
            assert!(k == 0 || shortest < 0.999, "{w} × {h}, level {k}: shortest {shortest}");
        }
    }
}
