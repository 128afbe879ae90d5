//! The sliding sums of the fit: a source row as the fit reads it, the
//! row sums along each row's windows and the window sums down the rows
//! (see the module docs of [`crate::fit`] for how they stay exact).

/// A source row as the fit reads it: heights, and the image column of the
/// first (a window's rows start left of the image's edge, or inside it).
pub(super) struct RowRef<'a, H> {
    pub(super) values: &'a [H],
    pub(super) x0: isize,
    /// Whether the row may hold holes (values read as 0 in the z sums).
    pub(super) holes: bool,
}

impl<H> Clone for RowRef<'_, H> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<H> Copy for RowRef<'_, H> {}

/// Source row v of the fit, for every v its patches reach: an image row,
/// or (beyond the image's top and bottom) the row the y border gives.
pub(super) type SourceRows<'s, 'a, H> = dyn Fn(isize) -> RowRef<'a, H> + Sync + 's;

/// One row's horizontal sums per column, as planes so the loops vectorise.
pub(super) struct RowSums {
    pub(super) s0: Vec<f64>,
    pub(super) si: Vec<f64>,
    pub(super) szz: Vec<f64>,
    /// Scratch: the row's heights with their borders.
    pub(super) padded: Vec<f64>,
    /// Scratch: a block's suffix and prefix sums (floats).
    pub(super) suffix: Vec<[f64; 3]>,
    pub(super) prefix: Vec<[f64; 3]>,
    /// Scratch: the squares of `padded` (floats).
    pub(super) squares: Vec<f64>,
}

impl RowSums {
    pub(super) fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        RowSums {
            s0: z.clone(),
            si: z.clone(),
            szz: z,
            padded: Vec::new(),
            suffix: Vec::new(),
            prefix: Vec::new(),
            squares: Vec::new(),
        }
    }
}

/// Blocks of a row summed side by side by [`BlockLanes::side_by_side`].
pub(super) const BLOCK_LANES: usize = 4;

/// The block-aligned suffix and prefix sums of [`BLOCK_LANES`] adjacent
/// blocks at once, one block a vector lane: each lane adds the same values
/// in the same order as one block alone, so the bits are the same, and the
/// chains of dependent additions of four blocks run side by side (one
/// block at a time, they were the N ≥ 9 fit's largest cost).
#[derive(Default)]
pub(super) struct BlockLanes {
    /// Value q of every block, lane l holding block l's.
    values: Vec<[f64; BLOCK_LANES]>,
    /// Σz, Σ(weight·z), Σz² of values q up to 2r (suffixes, index q) and of
    /// values 2r + 1 to 2r + t (prefixes, index t).
    suffix: Vec<[[f64; BLOCK_LANES]; 3]>,
    prefix: Vec<[[f64; BLOCK_LANES]; 3]>,
}

impl BlockLanes {
    /// The sums of [`BLOCK_LANES`] blocks of `n` (= 2r + 1) outputs, block
    /// l's value q (its column − r + q) being `z[l · n + q]`, each value
    /// weighted by `weight(q)`. Gives `out(l, t, [Σz, Σ weight·z, Σz²])` for
    /// output t of block l, over the values t to t + 2r: the suffix of
    /// values t to 2r plus the prefix 2r + 1 to 2r + t, each summed from
    /// its first value (as `Plan::blocked_row_sums` sums one block).
    #[inline(always)]
    pub(super) fn side_by_side(
        &mut self,
        n: usize,
        weight: impl Fn(usize) -> f64,
        z: &[f64],
        mut out: impl FnMut(usize, usize, [f64; 3]),
    ) {
        const L: usize = BLOCK_LANES;
        let BlockLanes { values, suffix, prefix } = self;
        values.resize(2 * n - 1, [0.0; L]);
        for l in 0..L {
            for (v, &z) in values.iter_mut().zip(&z[l * n..][..2 * n - 1]) {
                v[l] = z;
            }
        }
        suffix.resize(n, [[0.0; L]; 3]);
        prefix.resize(n, [[0.0; L]; 3]);
        let add = |sums: &mut [[f64; L]; 3], z: &[f64; L], w: f64| {
            for l in 0..L {
                sums[0][l] += z[l];
                sums[1][l] += w * z[l];
                sums[2][l] += z[l] * z[l];
            }
        };
        // Suffix q = 2r − i and prefix t = i + 1 (value 2r + 1 + i) in one
        // loop: six chains of vectors side by side.
        let (mut a, mut p) = ([[0.0; L]; 3], [[0.0; L]; 3]);
        for i in 0..n - 1 {
            let (q, t) = (n - 1 - i, i + 1);
            add(&mut a, &values[q], weight(q));
            suffix[q] = a;
            add(&mut p, &values[n + i], weight(n + i));
            prefix[t] = p;
        }
        add(&mut a, &values[0], weight(0));
        suffix[0] = a;
        prefix[0] = [[0.0; L]; 3];
        for l in 0..L {
            for (t, (s, p)) in suffix.iter().zip(prefix.iter()).enumerate() {
                out(l, t, [s[0][l] + p[0][l], s[1][l] + p[1][l], s[2][l] + p[2][l]]);
            }
        }
    }
}

/// The horizontal sums of the last source rows read, by row: slot v mod
/// the slots holds row v.
pub(super) struct RowCache {
    pub(super) rows: Vec<(isize, RowSums)>,
}

impl RowCache {
    pub(super) fn new(slots: usize, width: usize) -> Self {
        RowCache { rows: (0..slots).map(|_| (isize::MIN, RowSums::zeros(width))).collect() }
    }

    /// Row v's sums, which [`Self::get`] made last.
    pub(super) fn held(&self, v: isize) -> &RowSums {
        let (held, sums) = &self.rows[v.rem_euclid(self.rows.len() as isize) as usize];
        debug_assert_eq!(*held, v);
        sums
    }

    /// The slot for row v, to be filled with its sums, unless it holds
    /// them: the caller fills it at once. The strips' loops fill it
    /// themselves, so that the row sums are compiled inside them (for
    /// their instruction set) rather than in a closure called from here.
    #[inline(always)]
    pub(super) fn stale(&mut self, v: isize) -> Option<&mut RowSums> {
        let slot = v.rem_euclid(self.rows.len() as isize) as usize;
        let (held, sums) = &mut self.rows[slot];
        if *held == v {
            return None;
        }
        *held = v;
        Some(sums)
    }

    /// Row v's sums, made by `fill` unless held.
    #[inline(always)]
    pub(super) fn get(&mut self, v: isize, fill: &impl Fn(isize, &mut RowSums)) -> &RowSums {
        let slot = v.rem_euclid(self.rows.len() as isize) as usize;
        let (held, sums) = &mut self.rows[slot];
        if *held != v {
            fill(v, sums);
            *held = v;
        }
        sums
    }
}

/// The patch sums of the current output row, per column.
pub(super) struct WindowSums {
    pub(super) s0: Vec<f64>,
    pub(super) si: Vec<f64>,
    pub(super) sj: Vec<f64>,
    pub(super) szz: Vec<f64>,
    /// Whether each column's patch holds a hole (empty in a strip without
    /// holes): [`Plan::patch_holes`] refits it after [`Plan::emit`].
    pub(super) with_hole: Vec<bool>,
}

impl WindowSums {
    pub(super) fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        WindowSums { s0: z.clone(), si: z.clone(), sj: z.clone(), szz: z, with_hole: Vec::new() }
    }

    /// The first `w` texels' planes: Σz, Σiz, Σjz and Σz².
    #[inline(always)]
    pub(super) fn planes(&self, w: usize) -> [&[f64]; 4] {
        [&self.s0[..w], &self.si[..w], &self.sj[..w], &self.szz[..w]]
    }

    pub(super) fn clear(&mut self) {
        for plane in [&mut self.s0, &mut self.si, &mut self.sj, &mut self.szz] {
            plane.fill(0.0);
        }
    }

    /// The sums of a suffix and a prefix of rows, Σj·z moved by `shift`
    /// texels' weight (the rows' weights were counted from another row).
    #[inline(always)]
    pub(super) fn combine(&mut self, a: &WindowSums, b: &WindowSums, shift: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (a0, ai, aj, azz) = (&a.s0[..w], &a.si[..w], &a.sj[..w], &a.szz[..w]);
        let (b0, bi, bj, bzz) = (&b.s0[..w], &b.si[..w], &b.sj[..w], &b.szz[..w]);
        for x in 0..w {
            s0[x] = a0[x] + b0[x];
            si[x] = ai[x] + bi[x];
            sj[x] = (aj[x] + bj[x]) - shift * s0[x];
            szz[x] = azz[x] + bzz[x];
        }
    }

    /// The sums of the patch's N rows, `rows[j]` at vertical offset
    /// j − N/2, added in order.
    #[inline(always)]
    pub(super) fn sum_rows<const N: usize>(&mut self, rows: &[&RowSums; N]) {
        let w = self.s0.len();
        let planes = [&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]];
        patch_sums(rows, 0..w, planes);
    }

    /// `previous` plus the row sums `h` at vertical offset `j`.
    #[inline(always)]
    pub(super) fn set_sum(&mut self, previous: &WindowSums, h: &RowSums, j: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (p0, pi, pj, pzz) = (&previous.s0[..w], &previous.si[..w], &previous.sj[..w], &previous.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        for x in 0..w {
            s0[x] = p0[x] + h0[x];
            si[x] = pi[x] + hi[x];
            sj[x] = pj[x] + j * h0[x];
            szz[x] = pzz[x] + hzz[x];
        }
    }

    /// Adds the row sums `h` (offset `j`) to these prefix sums, and writes
    /// `out` = `suffix` + them, as [`Self::combine`] does, in one pass.
    #[inline(always)]
    pub(super) fn add_then_combine(
        &mut self,
        h: &RowSums,
        j: f64,
        suffix: &WindowSums,
        shift: f64,
        out: &mut WindowSums,
    ) {
        let w = self.s0.len();
        let (p0, pi, pj, pzz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        let (a0, ai, aj, azz) = (&suffix.s0[..w], &suffix.si[..w], &suffix.sj[..w], &suffix.szz[..w]);
        let (o0, oi, oj, ozz) = (&mut out.s0[..w], &mut out.si[..w], &mut out.sj[..w], &mut out.szz[..w]);
        for x in 0..w {
            p0[x] += h0[x];
            pi[x] += hi[x];
            pj[x] += j * h0[x];
            pzz[x] += hzz[x];
            o0[x] = a0[x] + p0[x];
            oi[x] = ai[x] + pi[x];
            oj[x] = (aj[x] + pj[x]) - shift * o0[x];
            ozz[x] = azz[x] + pzz[x];
        }
    }

    /// Adds the row sums `h` of the window's row at vertical offset `j`.
    #[inline(always)]
    pub(super) fn add(&mut self, h: &RowSums, j: f64) {
        // Every slice cut to one length: the loop then has no bounds
        // checks and vectorises.
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        for x in 0..w {
            s0[x] += h0[x];
            si[x] += hi[x];
            sj[x] += j * h0[x];
            szz[x] += hzz[x];
        }
    }

    /// Slides the window down one row: row sums `leaving` (offset −r) go,
    /// `entering` (offset r + 1 before the slide) come. Σj·z moves by
    /// r·leaving + (r + 1)·entering − the new Σz, as every row's offset
    /// drops by one.
    #[inline(always)]
    pub(super) fn slide(&mut self, leaving: &RowSums, entering: &RowSums, r: f64, r1: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (l0, li, lzz) = (&leaving.s0[..w], &leaving.si[..w], &leaving.szz[..w]);
        let (e0, ei, ezz) = (&entering.s0[..w], &entering.si[..w], &entering.szz[..w]);
        for x in 0..w {
            let new_s0 = s0[x] - l0[x] + e0[x];
            sj[x] += r * l0[x] + r1 * e0[x] - new_s0;
            s0[x] = new_s0;
            si[x] += ei[x] - li[x];
            szz[x] += ezz[x] - lzz[x];
        }
    }
}

/// Σz, Σiz, Σjz and Σz² of the patches of columns `texels` (of the rows'
/// planes) from their N rows' sums, into `[s0, si, sj, szz]`, each
/// `texels.len()` long: [`WindowSums::sum_rows`]' whole row, or the
/// one-pass emit's chunk, with the same bits.
#[inline(always)]
pub(super) fn patch_sums<const N: usize>(
    rows: &[&RowSums; N],
    texels: std::ops::Range<usize>,
    [s0, si, sj, szz]: [&mut [f64]; 4],
) {
    let r = N / 2;
    let h0: [&[f64]; N] = std::array::from_fn(|j| &rows[j].s0[texels.clone()]);
    let hi: [&[f64]; N] = std::array::from_fn(|j| &rows[j].si[texels.clone()]);
    let hzz: [&[f64]; N] = std::array::from_fn(|j| &rows[j].szz[texels.clone()]);
    // A pass per row and plane, each a loop of two slices that
    // vectorises (the sums stay in the core's first cache); every
    // texel's additions keep the rows' order. Σjz pairs the rows at ±d,
    // as the row sums pair the columns.
    for (out, h) in [(&mut *s0, &h0), (&mut *si, &hi), (&mut *szz, &hzz)] {
        out.iter_mut().zip(h[0]).zip(h[1]).for_each(|((a, p), q)| *a = p + q);
    }
    for j in 2..N {
        s0.iter_mut().zip(h0[j]).for_each(|(a, b)| *a += b);
        si.iter_mut().zip(hi[j]).for_each(|(a, b)| *a += b);
        szz.iter_mut().zip(hzz[j]).for_each(|(a, b)| *a += b);
    }
    sj.iter_mut().zip(h0[r + 1]).zip(h0[r - 1]).for_each(|((a, p), m)| *a = p - m);
    for d in 2..=r {
        let k = d as f64;
        sj.iter_mut().zip(h0[r + d]).zip(h0[r - d]).for_each(|((a, p), m)| *a += k * (p - m));
    }
}
