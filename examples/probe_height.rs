//! Scratch probe (not committed): heights report of a PNG height map's normals.
use normalfit::height::{HeightOptions, heights};
use normalfit::io::{ReadOptions, decode};
use normalfit::{Border, Borders, Fit, Options, Strength, normals};
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a[0] == "diff" {
        let read = |p: &str| decode(&std::fs::read(p).unwrap(), &ReadOptions::default()).unwrap().heights(None).unwrap();
        let (x, y) = (read(&a[1]), read(&a[2]));
        let (lo, hi) = x.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        let d = x.iter().zip(&y).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        println!("max diff {d:e} over range {:e}: {:e}", hi - lo, d / (hi - lo).max(f32::MIN_POSITIVE));
        return;
    }
    let raster = decode(&std::fs::read(&a[0]).unwrap(), &ReadOptions::default()).unwrap();
    let (w, h) = (raster.width, raster.height);
    let mut hs: Vec<f64> = raster.heights(None).unwrap().iter().map(|&v| f64::from(v)).collect();
    let (w, h) = if a.len() > 7 {
        let (cw, ch): (usize, usize) = (a[6].parse().unwrap(), a[7].parse().unwrap());
        hs = (0..cw * ch).map(|k| hs[(k / cw) * w + k % cw]).collect();
        (cw, ch)
    } else {
        (w, h)
    };
    let n: usize = a[1].parse().unwrap();
    let fit = if a[2] == "v" { Fit::Vertical } else { Fit::Orthogonal };
    let b = |s: &str| match s { "wrap" => Border::Wrap, "clamp" => Border::Clamp, _ => Border::Mirror };
    let borders = Borders { x: b(&a[3]), y: b(&a[4]) };
    let s: f64 = a[5].parse().unwrap();
    let opts = Options::new().with_patch(n).with_fit(fit).with_borders(borders).with_strength(Strength::Scale(s));
    let nm = normals(&hs, w, h, &opts).unwrap();
    let t = std::time::Instant::now();
    let back = heights(&nm, w, h, &HeightOptions::from_fit(&opts).with_step(f64::from(f32::EPSILON))).unwrap();
    let el = t.elapsed().as_secs_f64();
    let mean = hs.iter().sum::<f64>() / hs.len() as f64;
    let (lo, hi) = hs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let err = hs.iter().zip(&back.values).map(|(a, b)| (a - mean - b).abs()).fold(0.0f64, f64::max) / (hi - lo);
    let again = normals(&back.values.iter().map(|v| v * 1.0).collect::<Vec<f64>>(), w, h, &opts).unwrap();
    let fit_off = again.iter().zip(&nm).map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0f32, f32::max)).fold(0.0f32, f32::max);
    println!("{w}x{h} N {n} {fit:?} {borders:?}: normals of the result off by {fit_off:e}");
    println!("{w}x{h} N {n} {fit:?} {borders:?}: {el:.3} s, solves {}, converged {}, max err {err:.2e}", back.report.iterations, back.report.converged);
}
