//! What the mip chain tests share (tests/integration/mips.rs, the
//! library's chains; cli_mips.rs, the command line's): the box filter
//! written plainly, by overlap areas, and heights with detail at every
//! scale.

/// The mean of `values` (w × h) over each texel of a `(lw, lh)` grid laid
/// over the same area: the overlap of every input texel with the output
/// texel's footprint, as areas in input texels.
pub fn box_filter(values: &[f64], (w, h): (usize, usize), (lw, lh): (usize, usize)) -> Vec<f64> {
    let overlap = |a: f64, b: f64, t: usize| (b.min(t as f64 + 1.0) - a.max(t as f64)).max(0.0);
    let (fx, fy) = (w as f64 / lw as f64, h as f64 / lh as f64);
    let mut out = Vec::new();
    for j in 0..lh {
        for i in 0..lw {
            let (x0, x1, y0, y1) = (i as f64 * fx, (i + 1) as f64 * fx, j as f64 * fy, (j + 1) as f64 * fy);
            let mut sum = 0.0;
            for y in 0..h {
                for x in 0..w {
                    sum += overlap(x0, x1, x) * overlap(y0, y1, y) * values[y * w + x];
                }
            }
            out.push(sum / (fx * fy));
        }
    }
    out
}

/// Heights of every kind of detail: two waves and a ramp, as 16-bit
/// samples.
pub fn heights(w: usize, h: usize) -> Vec<u16> {
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let v = 0.5 + 0.2 * (x * 0.7).sin() * (y * 0.3).cos() + 0.1 * (x * 0.05 + y * 0.11).sin() + 0.002 * x;
            (v.clamp(0.0, 1.0) * 65535.0).round() as u16
        })
        .collect()
}
