//! Fits in real-world units (issue 17, docs/terrain.md): texels of unequal
//! spacing, per-row spacing of geographic rasters, heights as stored.
//!
//! The fast path is checked against the slow reference
//! (`tests/common/reference.rs`): for every texel, the N×N points
//! (sx·i, σ·sy·j, S·h) through the border maps at its centre row's
//! spacing, then for the vertical fit the ordinary least-squares plane
//! z = a + b·u + c·v from its 3×3 normal equations, and for the orthogonal
//! fit the eigenvector of the smallest eigenvalue of the points' 3×3
//! covariance by Jacobi rotations. Nothing is shared with the library's
//! sums.

use crate::common;

use std::sync::Arc;

use common::reference::{self, unit};
use normalfit::io::{Georef, ModelType, metres_per_degree};
use normalfit::units::{MapSpacing, map_spacing, slope_aspect};
use normalfit::{Border, Borders, Convention, Fit, FitRequest, Options, Spacing, Strength, Units};

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

/// Heights in metres: a tilted plane, a bump and hashed noise, so that the
/// patches are neither planar nor degenerate.
fn terrain(w: usize, h: usize, amplitude: f64) -> Vec<f64> {
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let noise = ((k as u64).wrapping_mul(2_654_435_761) % 1000) as f64 / 1000.0 - 0.5;
            amplitude * (0.3 * x - 0.2 * y + 2.0 * (-((x - 9.0).powi(2) + (y - 6.0).powi(2)) / 20.0).exp() + noise)
        })
        .collect()
}

fn fitted(z: &[f64], w: usize, h: usize, opts: &Options) -> (Vec<[f64; 3]>, Vec<f32>) {
    let mut n = vec![[0.0f64; 3]; w * h];
    let mut residual = vec![0.0f32; w * h];
    FitRequest::new(opts).residual(&mut residual).normals_into(z, w, h, &mut n).unwrap();
    (n, residual)
}

/// Unequal spacing, N = 3, 5, 9, both fits, every border mode on each axis,
/// both conventions: every texel's normal within 1e-9 of the reference and
/// its residual within 1e-5 relative (it is stored as f32).
#[test]
fn unequal_spacing_fits_as_the_dense_reference() {
    let (w, h) = (23, 17);
    let mut checked = 0;
    // The last: steep noise (slopes up to about 5) on texels 2000 × 3000
    // apart, where patches come near vertical but are not.
    let cases = [(1.0, 2.5, 1.0, 1.0), (30.0, 20.0, 25.0, 1.0), (0.7, 0.2, 0.3, 3.0), (2000.0, 3000.0, 20000.0, 1.0)];
    for (sx, sy, amplitude, scale) in cases {
        let z = terrain(w, h, amplitude);
        for n in [3, 5, 9] {
            for fit in [Fit::Vertical, Fit::Orthogonal] {
                for (k, (bx, by)) in BORDERS.iter().flat_map(|&x| BORDERS.iter().map(move |&y| (x, y))).enumerate() {
                    let convention = if k % 2 == 0 { Convention::OpenGl } else { Convention::DirectX };
                    let opts = Options::new()
                        .with_patch(n)
                        .with_fit(fit)
                        .with_borders(Borders { x: bx, y: by })
                        .with_convention(convention)
                        .with_strength(Strength::Scale(scale))
                        .with_units(Units::Map(Spacing::Uniform { x: sx, y: sy }));
                    let (got, residual) = fitted(&z, w, h, &opts);
                    for y in 0..h {
                        for x in 0..w {
                            let plane = reference::fit_at(&z, None, w, h, &opts, x, y).unwrap();
                            let (want, rms) = (plane.normal, plane.residual);
                            let g = got[y * w + x];
                            let err = (0..3).map(|c| (g[c] - want[c]).abs()).fold(0.0, f64::max);
                            assert!(
                                err < 1e-9,
                                "{sx}×{sy} N {n} {fit:?} {bx:?},{by:?} texel ({x}, {y}): {g:?} against {want:?}"
                            );
                            let r = f64::from(residual[y * w + x]);
                            assert!(
                                (r - rms).abs() <= 1e-5 * rms.max(1e-3 * amplitude),
                                "{sx}×{sy} N {n} {fit:?} residual at ({x}, {y}): {r} against {rms}"
                            );
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert_eq!(checked, cases.len() * 3 * 2 * 9 * w * h);
}

/// The orthogonal fit with unequal spacing is not the square grid's normal
/// scaled afterwards: on a noisy patch the two differ, and the reference
/// (checked above) sides with the fit in real-world lengths.
#[test]
fn the_orthogonal_fit_takes_the_spacing_in_its_moments() {
    let (w, h) = (23, 17);
    let z = terrain(w, h, 1.0);
    let (sx, sy) = (1.0, 3.0);
    let map = Options::new().with_patch(5).with_units(Units::Map(Spacing::Uniform { x: sx, y: sy }));
    let (got, _) = fitted(&z, w, h, &map);
    // Post-scaling: the square-grid orthogonal normal, its y slope divided by sy.
    let square = Options::new().with_patch(5).with_units(Units::Map(Spacing::square(1.0)));
    let (plain, _) = fitted(&z, w, h, &square);
    let most = got
        .iter()
        .zip(&plain)
        .map(|(g, p)| {
            let scaled = unit([p[0], p[1] / sy, p[2]]);
            (0..3).map(|c| (g[c] - scaled[c]).abs()).fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    assert!(most > 1e-3, "post-scaling differs from the fit by at most {most}");
}

/// Equal spacing of 1 in map units is the contract's fit of the same
/// values, bit for bit (normals and residual); equal spacing s is the
/// contract's fit with the gain divided by s, within rounding.
#[test]
fn equal_spacing_gives_todays_bits() {
    let (w, h) = (41, 29);
    let z = terrain(w, h, 0.8);
    let z32: Vec<f32> = z.iter().map(|&v| v as f32).collect();
    for n in [3, 5, 9, 33] {
        for fit in [Fit::Vertical, Fit::Orthogonal] {
            for border in BORDERS {
                let texels = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(Borders::both(border))
                    .with_strength(Strength::Scale(2.0));
                let map = texels.clone().with_units(Units::Map(Spacing::square(1.0)));
                let (a, b) = (fitted(&z, w, h, &texels), fitted(&z, w, h, &map));
                assert_eq!(a.0, b.0, "N {n} {fit:?} {border:?}: normals");
                assert_eq!(a.1, b.1, "N {n} {fit:?} {border:?}: residual");
                let mut a = vec![[0.0f32; 3]; w * h];
                let mut b = vec![[0.0f32; 3]; w * h];
                FitRequest::new(&texels).normals_into(&z32, w, h, &mut a).unwrap();
                FitRequest::new(&map).normals_into(&z32, w, h, &mut b).unwrap();
                assert_eq!(a, b, "N {n} {fit:?} {border:?}: f32 heights");
                // Square pixels of 30 m: the gain over 30.
                let metres = texels.clone().with_units(Units::Map(Spacing::square(30.0)));
                let over = texels.clone().with_strength(Strength::Scale(2.0 / 30.0));
                let (p, q) = (fitted(&z, w, h, &metres).0, fitted(&z, w, h, &over).0);
                let most =
                    p.iter().zip(&q).flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs())).fold(0.0, f64::max);
                assert!(most < 1e-14, "N {n} {fit:?} {border:?}: 30 m pixels {most}");
            }
        }
    }
}

/// Integer samples in map units are their stored values (a DEM's metres),
/// not value / (2^bits − 1).
#[test]
fn integers_in_map_units_are_their_stored_values() {
    let (w, h) = (19, 13);
    let stored: Vec<u16> = terrain(w, h, 40.0).iter().map(|v| (v + 1000.0).round() as u16).collect();
    let as_f64: Vec<f64> = stored.iter().map(|&v| f64::from(v)).collect();
    for fit in [Fit::Vertical, Fit::Orthogonal] {
        let opts = Options::new().with_fit(fit).with_units(Units::Map(Spacing::Uniform { x: 30.0, y: 20.0 }));
        let a = normalfit::normals(&stored, w, h, &opts).unwrap();
        let b = normalfit::normals(&as_f64, w, h, &opts).unwrap();
        assert_eq!(a, b, "{fit:?}");
    }
}

/// A plane of known slope gives exactly its slope and aspect with unequal
/// spacing, both fits, N = 3, 5, 9, away from the borders (which bend a
/// plane), in both conventions: to 1e-7°, the rounding of the patch sums
/// of heights near 1000 m (Czz is Σz² − (Σz)²/N² of them).
#[test]
fn planes_give_exactly_their_slope_and_aspect() {
    let (w, h) = (30, 24);
    for (sx, sy) in [(30.0, 20.0), (10.0, 10.0), (1.5, 4.0)] {
        for (p, q) in [(0.3, 0.1), (-0.7, 0.0), (0.0, 2.5), (-0.05, -0.12), (3.0, -4.0)] {
            // h = p · east + q · north; row 0 is north, rows go south.
            let z: Vec<f64> = (0..w * h).map(|k| p * (k % w) as f64 * sx - q * (k / w) as f64 * sy + 1000.0).collect();
            let slope = p.hypot(q).atan().to_degrees();
            let aspect = {
                let a = (-p).atan2(-q).to_degrees();
                if a < 0.0 { a + 360.0 } else { a }
            };
            for n in [3, 5, 9] {
                for fit in [Fit::Vertical, Fit::Orthogonal] {
                    for convention in [Convention::OpenGl, Convention::DirectX] {
                        let opts = Options::new()
                            .with_patch(n)
                            .with_fit(fit)
                            .with_convention(convention)
                            .with_units(Units::Map(Spacing::Uniform { x: sx, y: sy }));
                        let normals = fitted(&z, w, h, &opts).0;
                        let r = n / 2;
                        for y in r..h - r {
                            for x in r..w - r {
                                let got = slope_aspect(normals[y * w + x], convention);
                                let what = format!("{sx}×{sy} ({p}, {q}) N {n} {fit:?} {convention:?} ({x}, {y})");
                                assert!(
                                    (got.slope - slope).abs() < 1e-7,
                                    "{what}: slope {} against {slope}",
                                    got.slope
                                );
                                let a = got.aspect.expect("a tilted plane has an aspect");
                                let d = (a - aspect + 540.0).rem_euclid(360.0) - 180.0;
                                assert!(d.abs() < 1e-7, "{what}: aspect {a} against {aspect}");
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A geographic raster (EPSG 4326 style, 0.05° pixels from 60° N) of the
/// surface h = p · lon + q · lat: its gradient at a row is p per degree of
/// longitude and q per degree of latitude, in metres at that row's
/// latitude. Each texel's patch takes its centre row's spacing, so the fit
/// gives that gradient exactly; the neighbouring rows' spacings would give
/// another, far beyond the tolerance, so the test tells them apart.
#[test]
fn geographic_rows_take_their_centre_rows_spacing() {
    let (w, h) = (16, 40);
    let (step, top) = (0.05, 60.0);
    let mut georef = Georef::default();
    georef.pixel_scale = Some([step, step, 0.0]);
    georef.tiepoints = vec![[0.0, 0.0, 0.0, 10.0, top, 0.0]];
    georef.model = Some(ModelType::Geographic);
    let spacing = map_spacing(Some(&georef), h).unwrap();
    let Spacing::Rows(rows) = &spacing else { panic!("a geographic raster has a spacing per row") };
    assert_eq!(rows.len(), h);
    // Row y's centre is at latitude top − (y + 0.5) · step.
    for (y, row) in rows.iter().enumerate() {
        let (east, north) = metres_per_degree(top - (y as f64 + 0.5) * step);
        assert!((row[0] - step * east).abs() < 1e-6 && (row[1] - step * north).abs() < 1e-6, "row {y}");
    }
    let (p, q) = (900.0, -400.0);
    let z: Vec<f64> =
        (0..w * h).map(|k| p * (10.0 + (k % w) as f64 * step) + q * (top - (k / w) as f64 * step)).collect();
    for n in [3, 9] {
        for fit in [Fit::Vertical, Fit::Orthogonal] {
            let opts = Options::new().with_patch(n).with_fit(fit).with_units(Units::Map(spacing.clone()));
            let normals = fitted(&z, w, h, &opts).0;
            let r = n / 2;
            for y in r..h - r {
                let (east, north) = metres_per_degree(top - (y as f64 + 0.5) * step);
                let truth = |e: f64, nn: f64| (p / e).hypot(q / nn).atan().to_degrees();
                let want = truth(east, north);
                let (e2, n2) = metres_per_degree(top - (y as f64 + 1.5) * step);
                assert!((truth(e2, n2) - want).abs() > 1e-4, "neighbouring rows differ");
                for x in r..w - r {
                    let got = slope_aspect(normals[y * w + x], Convention::OpenGl).slope;
                    assert!((got - want).abs() < 1e-9, "N {n} {fit:?} ({x}, {y}): {got} against {want}");
                }
            }
        }
    }
}

/// Per-row spacing against the reference, each texel at its centre row's
/// spacing, on noisy heights, N = 5, every border mode.
#[test]
fn per_row_spacing_fits_as_the_reference() {
    let (w, h) = (21, 15);
    let z = terrain(w, h, 30.0);
    let rows: Vec<[f64; 2]> = (0..h).map(|y| [20.0 + 3.0 * y as f64, 25.0 - y as f64]).collect();
    for fit in [Fit::Vertical, Fit::Orthogonal] {
        for border in BORDERS {
            let opts = Options::new()
                .with_patch(5)
                .with_fit(fit)
                .with_borders(Borders::both(border))
                .with_units(Units::Map(Spacing::Rows(Arc::from(rows.clone()))));
            let got = fitted(&z, w, h, &opts).0;
            for y in 0..h {
                for x in 0..w {
                    let want = reference::normal_at(&z, w, h, &opts, x, y);
                    let g = got[y * w + x];
                    let err = (0..3).map(|c| (g[c] - want[c]).abs()).fold(0.0, f64::max);
                    assert!(err < 1e-9, "{fit:?} {border:?} ({x}, {y}): {g:?} against {want:?}");
                }
            }
        }
    }
}

/// Rows of every kind in one image: ρ = sy / sx below 1, exactly 1 (the
/// square grid's loop) and above 1 (the unequal spacing's loops over
/// planes), row after row, in an image wide enough for three strips of
/// the fit, N = 3, 5, 9, both fits, every border pair: each texel checked
/// (near the edges, the strips' joins and every 37th column) against the
/// reference; and the same bits on one thread as on three, and band by
/// band ([`BandFit`]) as whole.
#[test]
fn rows_of_mixed_spacing_across_strips_fit_as_the_reference() {
    let (w, h) = (1100, 9);
    let z = terrain(w, h, 30.0);
    let rows: Vec<[f64; 2]> = (0..h).map(|y| [[10.0, 10.0], [8.0, 11.3], [12.0, 7.0]][y % 3]).collect();
    let checked = |x: usize| {
        x < 40 || x >= w - 40 || (490..540).contains(&x) || (1000..1050).contains(&x) || x.is_multiple_of(37)
    };
    for n in [3, 5, 9] {
        for fit in [Fit::Vertical, Fit::Orthogonal] {
            for (bx, by) in BORDERS.iter().flat_map(|&x| BORDERS.iter().map(move |&y| (x, y))) {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(Borders { x: bx, y: by })
                    .with_units(Units::Map(Spacing::Rows(Arc::from(rows.clone()))));
                let run = |threads: usize| {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    pool.install(|| fitted(&z, w, h, &opts).0)
                };
                let got = run(3);
                for y in 0..h {
                    for x in (0..w).filter(|&x| checked(x)) {
                        let want = reference::normal_at(&z, w, h, &opts, x, y);
                        let g = got[y * w + x];
                        let err = (0..3).map(|c| (g[c] - want[c]).abs()).fold(0.0, f64::max);
                        assert!(err < 1e-9, "N {n} {fit:?} {bx:?},{by:?} ({x}, {y}): {g:?} against {want:?}");
                    }
                }
                let bits = |normals: &[[f64; 3]]| normals.iter().map(|t| t.map(f64::to_bits)).collect::<Vec<_>>();
                assert!(bits(&run(1)) == bits(&got), "N {n} {fit:?} {bx:?},{by:?}: one thread");
                let bands = normalfit::fit::BandFit::new(w, h, &opts).unwrap();
                let mut streamed = Vec::new();
                for band in bands.bands() {
                    let mut out = vec![[0.0f64; 3]; band.len() * w];
                    bands.fit_band(band, &|y| &z[y * w..][..w], &mut out).unwrap();
                    streamed.extend(out);
                }
                assert!(bits(&streamed) == bits(&got), "N {n} {fit:?} {bx:?},{by:?}: bands");
            }
        }
    }
}

/// Where the spacing comes from, and the one-line errors when it cannot.
#[test]
fn the_spacing_of_a_georeference_and_its_errors() {
    let utm = |scale: [f64; 3]| {
        let mut g = Georef::default();
        g.pixel_scale = Some(scale);
        g.tiepoints = vec![[0.0, 0.0, 0.0, 500_000.0, 4_500_000.0, 0.0]];
        g.model = Some(ModelType::Projected);
        g.epsg = Some(32633);
        g
    };
    let with = |mut g: Georef, change: &dyn Fn(&mut Georef)| {
        change(&mut g);
        g
    };
    assert_eq!(map_spacing(Some(&utm([30.0, 20.0, 0.0])), 5).unwrap(), Spacing::Uniform { x: 30.0, y: 20.0 });
    // Feet of the map, metres of height: the spacing in metres.
    let feet = with(utm([100.0, 100.0, 0.0]), &|g| g.linear_unit = Some(9002));
    let Spacing::Uniform { x, y } = map_spacing(Some(&feet), 5).unwrap() else { panic!() };
    assert!((x - 30.48).abs() < 1e-12 && (y - 30.48).abs() < 1e-12);
    // Heights in feet, map in metres: the spacing in feet.
    let heights_in_feet = with(utm([30.48, 30.48, 0.0]), &|g| g.vertical_unit = Some(9002));
    let Spacing::Uniform { x, .. } = map_spacing(Some(&heights_in_feet), 5).unwrap() else { panic!() };
    assert!((x - 100.0).abs() < 1e-9);

    let message = |g: Option<&Georef>| map_spacing(g, 5).unwrap_err().to_string();
    assert!(message(None).contains("no georeferencing"), "{}", message(None));
    let no_transform = with(Georef::default(), &|g| g.nodata = Some(-9999.0));
    assert!(message(Some(&no_transform)).contains("no georeferencing"));
    let rotated = with(utm([30.0, 30.0, 0.0]), &|g| {
        g.transformation =
            Some([30.0, 5.0, 0.0, 500_000.0, 5.0, -30.0, 0.0, 4_500_000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    });
    // Columns (30, 5) and rows (5, −30): turned atan(5/30) = 9.462°, square.
    assert!(
        message(Some(&rotated)).contains("rotated 9.462° counter-clockwise from north-up"),
        "{}",
        message(Some(&rotated))
    );
    assert!(message(Some(&rotated)).contains("b = 5 and d = 5"), "{}", message(Some(&rotated)));
    let sheared = with(utm([30.0, 30.0, 0.0]), &|g| {
        g.transformation =
            Some([30.0, 10.0, 0.0, 500_000.0, 0.0, -30.0, 0.0, 4_500_000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    });
    // Rows (10, −30) against columns (30, 0): they meet at 90° − atan(1/3).
    assert!(
        message(Some(&sheared)).contains("sheared (its rows and columns meet at 71.565°"),
        "{}",
        message(Some(&sheared))
    );
    let geocentric = with(utm([30.0, 30.0, 0.0]), &|g| g.model = Some(ModelType::Geocentric));
    assert!(message(Some(&geocentric)).contains("model is geocentric"));
    let unknown_unit = with(utm([30.0, 30.0, 0.0]), &|g| g.linear_unit = Some(9999));
    assert!(message(Some(&unknown_unit)).contains("EPSG 9999"));
    for m in [message(None), message(Some(&rotated)), message(Some(&sheared)), message(Some(&unknown_unit))] {
        assert!(!m.contains('\n'), "{m}");
    }

    // A given pixel size wins over the file's, and is checked.
    let given = MapSpacing::Given { x: 2.0, y: 3.0 }.units(Some(&utm([30.0, 30.0, 0.0])), 5).unwrap();
    assert_eq!(given, Units::Map(Spacing::Uniform { x: 2.0, y: 3.0 }));
    assert!(MapSpacing::Given { x: 0.0, y: 3.0 }.units(None, 5).is_err());
    assert!(MapSpacing::Given { x: f64::NAN, y: 3.0 }.units(None, 5).is_err());
    assert_eq!(normalfit::units::parse_pixel_size("30,20").unwrap(), [30.0, 20.0]);
    assert_eq!(normalfit::units::parse_pixel_size("10").unwrap(), [10.0, 10.0]);
    for bad in ["", "0", "-1", "1,", "a,b", "inf", "1,2,3"] {
        assert!(normalfit::units::parse_pixel_size(bad).is_err(), "{bad}");
    }
    // Options refuse a bad spacing, and a per-row spacing of the wrong length.
    let bad = Options::new().with_units(Units::Map(Spacing::Uniform { x: -1.0, y: 1.0 }));
    assert!(bad.validate().is_err());
    let short = Options::new().with_units(Units::Map(Spacing::Rows(Arc::from(vec![[1.0, 1.0]; 3]))));
    let e = normalfit::normals(&[0.0f32; 20], 5, 4, &short).unwrap_err().to_string();
    assert!(e.contains("3 rows") && e.contains("4"), "{e}");
}

/// Slope and aspect of normals in both conventions, GDAL's compass.
#[test]
fn slope_and_aspect_follow_the_compass() {
    let s = 0.5f64.sqrt();
    let cases = [
        ([0.0, s, s], Convention::OpenGl, 0.0),
        ([s, 0.0, s], Convention::OpenGl, 90.0),
        ([0.0, -s, s], Convention::OpenGl, 180.0),
        ([-s, 0.0, s], Convention::OpenGl, 270.0),
        ([0.0, -s, s], Convention::DirectX, 0.0),
        ([0.5, 0.5, s], Convention::OpenGl, 45.0),
    ];
    for (n, convention, aspect) in cases {
        let got = slope_aspect(n, convention);
        assert!((got.slope - 45.0).abs() < 1e-9, "{n:?}");
        assert!((got.aspect.unwrap() - aspect).abs() < 1e-9, "{n:?} {convention:?}: {:?}", got.aspect);
    }
    let flat = slope_aspect([0.0, 0.0, 1.0], Convention::OpenGl);
    assert_eq!((flat.slope, flat.aspect), (0.0, None));
}

/// The program: `--units map` of a file without georeferencing is refused
/// in one line naming it, exit 2, no output; `--pixel-size X,Y` fits a
/// 16-bit PNG's stored values on that spacing, so a plane of stored
/// values comes out with its slope and aspect; a bad pixel size is a
/// usage error.
#[cfg(feature = "cli")]
#[test]
fn the_program_refuses_map_units_without_a_spacing_and_takes_a_pixel_size() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_normalfit");
    let (w, h) = (9u32, 7u32);
    // Stored values: 1000 + 3·x − 2·y (metres, say), on 10 × 4 m pixels:
    // a slope of 0.3 east and 0.5 north.
    let png = dir.path().join("dem.png");
    let pixels: Vec<u16> = (0..w * h).map(|k| (1000 + 3 * (k % w) - 2 * (k / w)) as u16).collect();
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, pixels).unwrap().save(&png).unwrap();

    let refused = dir.path().join("refused.exr");
    let o = Command::new(bin)
        .args(["convert", png.to_str().unwrap(), "--units", "map", "-o"])
        .arg(&refused)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("dem.png") && err.contains("no georeferencing") && err.contains("pixel size"), "{err}");
    assert!(!refused.exists());

    let out = dir.path().join("n.exr");
    let args = ["--pixel-size", "10,4", "--border", "clamp", "--fit", "orthogonal", "--signed", "-o"];
    let o = Command::new(bin).arg("convert").arg(&png).args(args).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let raster = normalfit::io::read_path(&out, &normalfit::io::ReadOptions::default()).unwrap();
    let plane = |name: &str| raster.plane(name).unwrap().data.clone();
    let (r, g, b) = (plane("R"), plane("G"), plane("B"));
    let k = 3 * w as usize + 4;
    let n = [r.height(k).unwrap(), g.height(k).unwrap(), b.height(k).unwrap()];
    let got = slope_aspect(n, Convention::OpenGl);
    let slope = 0.3f64.hypot(0.5).atan().to_degrees();
    let aspect = (-0.3f64).atan2(-0.5).to_degrees() + 360.0;
    assert!((got.slope - slope).abs() < 1e-4, "{got:?} against {slope}");
    assert!((got.aspect.unwrap() - aspect).abs() < 1e-4, "{got:?} against {aspect}");

    for bad in ["0", "1,-2", "x", "1,2,3"] {
        let o = Command::new(bin)
            .arg("convert")
            .arg(&png)
            .args(["--pixel-size", bad, "-o"])
            .arg(&refused)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(String::from_utf8_lossy(&o.stderr).contains("pixel size"), "{bad}");
    }
}
