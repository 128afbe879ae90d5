//! The plan of a fit: everything that is the same for every tile (the
//! patch, the gain, the borders, the blocks of rows), and the tiles and
//! strips the rows are cut into for the threads.

use std::ops::Range;

use crate::par::prelude::*;

use crate::error::Result;
use crate::options::{Borders, Fit, Options, Spacing, Units, Weights};
use crate::samples::Sample;

use super::emit::{EmitScratch, normal_from_sums, squared_distance_sum, store_normals};
use super::masked::{MaskSums, MaskedRow, Moments};
use super::sums::{BLOCK_LANES, BlockLanes, RowCache, RowRef, RowSums, SourceRows, WindowSums, patch_sums};
use super::unequal::RowSpacing;
use super::{Texel, checked_len};

/// Texels per branch between the two loops of the orthogonal fit's
/// normals (see [`Plan::emit_with`]).
pub(super) const EMIT_CHUNK: usize = 32;

/// Columns per parallel task of the fit (at least 8·N): the
/// task's sums (a few rows of f64 per column) then fit in a core's cache.
pub(super) const STRIP_COLS: usize = 512;

/// Texels a block of rows holds at least (unless the image is smaller):
/// a narrow image's blocks are tall enough that a block's work outweighs
/// setting it up.
pub(super) const MIN_BLOCK_TEXELS: usize = 1 << 14;

/// Texels a block of rows, and a band of blocks, holds at most (unless one
/// row is longer): what a streaming caller holds stays bounded whatever the
/// width.
pub(super) const MAX_BLOCK_TEXELS: usize = 1 << 24;

/// A strip's holes: the valid points' moments, the strip's rows of
/// `valid`, and the nodata value.
pub(super) struct StripHoles<'t> {
    pub(super) mask: MaskSums,
    pub(super) patches: MaskedRow,
    pub(super) valid: Vec<&'t mut [bool]>,
    pub(super) nodata: f64,
    /// With weights: the valid points' weighted moments (the integer
    /// `mask` still decides which patches hold a hole and which determine
    /// a plane: the weights are all positive, so they change neither).
    pub(super) weighted: Option<super::masked::WeightedMask>,
}

/// One parallel task of the fit: a strip of a tile, its rows from `y0`,
/// its columns from `x0`, as pieces of the output rows (and of the
/// residual rows, when asked for).
pub(super) struct Strip<'t, T> {
    pub(super) y0: usize,
    pub(super) x0: usize,
    pub(super) out: Vec<&'t mut [T]>,
    pub(super) residual: Option<Vec<&'t mut [f32]>>,
    /// With holes: whether each texel has a normal, by row, and the
    /// nodata value.
    pub(super) valid: Option<(Vec<&'t mut [bool]>, f64)>,
}

/// How a strip's sums are made ([`Plan::kernel`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Kernel {
    /// Running sums of stored integers: a ring of N rows' sums.
    Sliding,
    /// Each patch summed outright (floats, N ≤ 7; stored integers, N = 3):
    /// N rows' sums.
    Direct,
    /// Suffixes and prefixes of blocks aligned on the image (floats):
    /// 2N rows' sums and N window sums.
    Blocked,
    /// Weighted sums, each patch's outright (any sample type, with
    /// [`Weights::Binomial`]): N rows' sums (`super::weighted`).
    Weighted,
}

/// Everything about a conversion that is the same for every tile.
#[derive(Clone)]
pub(super) struct Plan {
    pub(super) width: usize,
    pub(super) n: usize,
    pub(super) r: usize,
    /// S: surface z per unit of height, sign included. The fit multiplies
    /// the samples by S times their unit ([`Sample::UNIT`]).
    pub(super) scale: f64,
    pub(super) sigma: f64,
    pub(super) fit: Fit,
    /// A = Σ i² over the patch (with weights, Σ w(i)·w(j)·i²).
    pub(super) a: f64,
    /// The patch's total weight: N² unweighted, 1 with weights (theirs
    /// sum to 1). Czz = Σz² − (Σz)²/`count`.
    pub(super) count: f64,
    /// [`Options::weights`].
    pub(super) weights: Weights,
    /// With weights, one axis's: w(k), w(k)·u and w(k)·u² at u = k − r
    /// (empty unweighted).
    pub(super) axis: [Vec<f64>; 3],
    /// With binomial weights from [`super::convolve::FFT_FROM`] on: the
    /// transforms of the sums by blocks (`None`: summed directly).
    pub(super) blocks: Option<std::sync::Arc<super::convolve::Blocks>>,
    pub(super) borders: Borders,
    pub(super) height: usize,
    pub(super) block_rows: usize,
    /// Emit each texel's patch moments [Cx, Cy, Czz] instead of its normal
    /// (the height inverse's re-fit, [`BandFit::moments`]).
    pub(super) moments: bool,
    /// Map units ([`Units::Map`]): the texel spacing, and heights taken as
    /// the values given whatever their type. `None`: the contract's units.
    pub(super) spacing: Option<Spacing>,
    /// [`Options::nodata`].
    pub(super) nodata: Option<f64>,
    /// The normal written at a missing texel ([`FitRequest::missing`]).
    pub(super) missing: [f64; 3],
    /// What the texels need beside their normals ([`super::Texel`]).
    pub(super) frame: super::TexelFrame,
    /// Detail at several scales ([`Options::detail`]): the sizes and
    /// weights whose slopes are summed, N the largest; empty for one patch
    /// size. Callers fit through `super::detail`, which runs each size's
    /// plan when it is set ([`Self::fit_rows`] fits one size).
    pub(super) detail: Vec<(usize, f64)>,
}

impl Plan {
    pub(super) fn new(width: usize, height: usize, opts: &Options) -> Result<Plan> {
        opts.validate()?;
        checked_len(width, height)?;
        // One scale of weight 1 is its size's own fit, bit for bit.
        let (n, detail) = match &opts.detail {
            None => (opts.patch, Vec::new()),
            Some(d) => match d.as_single() {
                Some(n) => (n, Vec::new()),
                None => (d.largest_patch(), d.scales().to_vec()),
            },
        };
        let spacing = match &opts.units {
            Units::Texels => None,
            Units::Map(spacing) => {
                spacing.validate(Some(height))?;
                Some(spacing.clone())
            }
        };
        let plan = Plan {
            width,
            n: 0,
            r: 0,
            scale: opts.scale_for_width(width),
            sigma: opts.convention.sigma(),
            fit: opts.fit,
            a: 0.0,
            count: 0.0,
            weights: opts.weights,
            axis: Default::default(),
            blocks: None,
            borders: opts.borders,
            height,
            block_rows: 0,
            moments: false,
            spacing,
            nodata: opts.nodata,
            missing: [0.0, 0.0, 1.0],
            frame: super::TexelFrame::new(opts.convention),
            detail: Vec::new(),
        };
        Ok(Plan { detail, ..plan.with_patch(n) })
    }

    /// The same plan for patch size `n` (odd, ≥ 3), of that one size.
    pub(super) fn with_patch(&self, n: usize) -> Plan {
        let r = n / 2;
        let tile = (8 * n).max(64);
        // Rows of a block: at least a tile, more for a narrow image, fewer
        // (down to one) for a very wide one (see the module docs).
        let width = self.width;
        let block_rows = tile.max(MIN_BLOCK_TEXELS.div_ceil(width)).min((MAX_BLOCK_TEXELS / width).max(1));
        let rf = r as f64;
        if self.weights != Weights::Uniform {
            // Σ w(i)·w(j)·i² = Σ w(i)·i², the w(j) summing to 1.
            let w = self.weights.axis(n);
            let wu: Vec<f64> = w.iter().enumerate().map(|(k, w)| w * (k as f64 - rf)).collect();
            let wuu: Vec<f64> = wu.iter().enumerate().map(|(k, wu)| wu * (k as f64 - rf)).collect();
            let a = wuu.iter().sum();
            // By blocks, a tile (and so a streaming caller's band) holds
            // whole blocks of rows: their inputs are the rows it reads.
            let blocks = super::convolve::block_len(self.weights, n)
                .map(|len| std::sync::Arc::new(super::convolve::Blocks::new(len, &w, &wu)));
            let block_rows = blocks.as_ref().map_or(block_rows, |b| block_rows.div_ceil(b.len) * b.len);
            let axis = [w, wu, wuu];
            return Plan { n, r, a, count: 1.0, axis, blocks, block_rows, detail: Vec::new(), ..self.clone() };
        }
        let a = n as f64 * rf * (rf + 1.0) * (2.0 * rf + 1.0) / 3.0;
        let count = (n * n) as f64;
        let axis = Default::default();
        Plan { n, r, a, count, axis, blocks: None, block_rows, detail: Vec::new(), ..self.clone() }
    }

    /// Fits the output rows from `y0`, columns `cols`, into `out` (rows of
    /// `cols.len()` texels), tile by tile and strip by strip in parallel.
    /// `rows(v)` gives source row v for every v the patches reach (beyond
    /// the image's edges too: the caller's source maps them). `residual`,
    /// when given, holds as many texels as `out` and gets the fit's RMS
    /// distances.
    ///
    /// Every texel's sums come from its own patch by the same operations
    /// whichever tile, strip or window holds it (see the module docs), so
    /// the cuts change no result. Tiles: the top r rows, then `block_rows`
    /// at a time, so that a streaming caller's bands are whole tiles.
    /// Strips of about 512 columns are the tasks that run in parallel: many
    /// small tasks keep both cores busy beside the pipeline's other threads
    /// (two tasks a band left one core idle while the other finished its
    /// tile), and a strip's sums stay in the core's cache.
    pub(super) fn fit_rows<'a, H: Sample, T: Texel>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        unit: f64,
        (y0, cols): (usize, Range<usize>),
        out: &mut [T],
        residual: Option<&mut [f32]>,
        valid: Option<(&mut [bool], f64)>,
    ) {
        let w = cols.len();
        let strip = self.strip_cols();
        let mut tasks: Vec<Strip<'_, T>> = Vec::new();
        let nodata = valid.as_ref().map(|v| v.1);
        let (mut y, mut rest, mut rest_residual) = (y0, out, residual);
        let mut rest_valid = valid.map(|v| v.0);
        while !rest.is_empty() {
            let tile_rows = if y < self.r { self.r - y } else { self.block_rows - (y - self.r) % self.block_rows };
            let len = (tile_rows * w).min(rest.len());
            let (tile, tail) = rest.split_at_mut(len);
            let (tile_residual, residual_tail) = match rest_residual {
                Some(r) => {
                    let (head, tail) = r.split_at_mut(len);
                    (Some(head), Some(tail))
                }
                None => (None, None),
            };
            let (tile_valid, valid_tail) = match rest_valid {
                Some(v) => {
                    let (head, tail) = v.split_at_mut(len);
                    (Some(head), Some(tail))
                }
                None => (None, None),
            };
            let first = tasks.len();
            // A piece of each of the tile's rows (16 bytes), sized once:
            // a 2^24-row column has 2^24 of them.
            let rows_here = len / w;
            for x0 in cols.clone().step_by(strip) {
                let has_residual = tile_residual.is_some();
                let valid = nodata.map(|nd| (Vec::with_capacity(rows_here), nd));
                let residual = has_residual.then(|| Vec::with_capacity(rows_here));
                tasks.push(Strip { y0: y, x0, out: Vec::with_capacity(rows_here), residual, valid });
            }
            if let Some(tile_valid) = tile_valid {
                for row in tile_valid.chunks_exact_mut(w) {
                    for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                        task.valid.as_mut().expect("a valid strip").0.push(piece);
                    }
                }
            }
            for row in tile.chunks_exact_mut(w) {
                for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                    task.out.push(piece);
                }
            }
            if let Some(tile_residual) = tile_residual {
                for row in tile_residual.chunks_exact_mut(w) {
                    for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                        task.residual.as_mut().expect("a residual strip").push(piece);
                    }
                }
            }
            y += tile_rows;
            rest = tail;
            rest_residual = residual_tail;
            rest_valid = valid_tail;
        }
        let kernel = self.kernel(unit);
        // Map units take every value as it is given (a DEM's metres).
        let unit = if self.spacing.is_some() { 1.0 } else { unit };
        // The product of S and the unit, once: every path that fits these
        // samples forms the same gain, and so the same bits.
        let gain = self.scale * unit;
        // Stored integers are summed as they are, exactly, whatever the
        // kernel, and the gain comes after, in the normals; floats are
        // scaled first.
        let gains = if self.sums_integers(unit) { (1.0, gain) } else { (gain, 1.0) };
        // The strips' sums are loops across the columns: compiled, with the
        // strip's whole loop inlined, for the widest vectors the processor
        // has (as `EmitRow` is). Rust fuses no multiply with an add and
        // each operation rounds alike in every instruction set: the same
        // bits on every processor.
        tasks.into_par_iter().for_each(|task| {
            pulp::Arch::new().dispatch(
                #[inline(always)]
                || match (kernel, self.n) {
                    (Kernel::Weighted, _) => self.fit_strip_weighted(rows, gain, task),
                    (Kernel::Sliding, _) => self.fit_strip_sliding(rows, gain, task),
                    (Kernel::Direct, 3) => self.fit_strip_direct::<H, T, 3>(rows, gains, task),
                    (Kernel::Direct, 5) => self.fit_strip_direct::<H, T, 5>(rows, gains, task),
                    (Kernel::Direct, 7) => self.fit_strip_direct::<H, T, 7>(rows, gains, task),
                    _ => self.fit_strip_blocked(rows, gain, task),
                },
            )
        });
    }

    /// How [`Self::fit_rows`] sums samples whose height is value × `unit`
    /// ([`Sample::UNIT`], or the caller's): stored integers (a unit below
    /// 1: 1/255, 1/65535) by running sums, unless map units take the
    /// values as given; floats outright for N ≤ 7, else by blocks. At
    /// N = 3 stored integers are summed outright too: their sums are exact
    /// either way (the same bits), and the row's running sum is a chain of
    /// dependent additions where the outright sums vectorise (4096² 16-bit
    /// heights to 8-bit RGB: 0.79× the time orthogonal, 0.84× vertical;
    /// at N = 5, 1.10× and 1.27×, so larger patches keep running sums).
    pub(super) fn kernel(&self, unit: f64) -> Kernel {
        if self.weights != Weights::Uniform {
            Kernel::Weighted
        } else if self.sums_integers(unit) && self.n > 3 {
            Kernel::Sliding
        } else if self.n <= 7 {
            Kernel::Direct
        } else {
            Kernel::Blocked
        }
    }

    /// Whether samples of `unit` are summed as the integers they store
    /// (a unit below 1), the gain applied after: not in map units, which
    /// take every value as it is given.
    fn sums_integers(&self, unit: f64) -> bool {
        self.spacing.is_none() && unit != 1.0
    }

    /// The bytes [`Self::fit_rows`] allocates, beyond its caller's
    /// buffers, to fit `rows` output rows of `cols` columns from samples
    /// of `unit`: the tasks and their lists of row pieces (of the normals,
    /// and of the residual and validity when asked for), and a strip's
    /// sums ([`Self::strip_bytes`]) on every thread at once. This grows
    /// with N (a strip holds up to 2N rows' sums of at least 8·N columns)
    /// and with the width only up to a strip's. An upper bound: a vector
    /// grown by doubling counts twice its length. The memory rule
    /// ([`crate::memory`]) compares it with what the process may take.
    pub(super) fn work_bytes(&self, unit: f64, (cols, rows): (usize, usize), holes: bool, residual: bool) -> u64 {
        let strip = self.strip_cols();
        let (w, strips) = (cols.min(strip) as u64, cols.div_ceil(strip) as u64);
        // The top r rows, then blocks: one tile more than whole blocks.
        let tasks = strips.saturating_mul(rows.div_ceil(self.block_rows) as u64 + 1);
        let buffers = 1 + u64::from(residual) + u64::from(holes);
        // 16 bytes a piece of a row; a task about 100, in a vector grown
        // by doubling.
        let lists = tasks.saturating_mul(2 * 128).saturating_add(strips * rows as u64 * 16 * buffers);
        let running = (crate::par::current_num_threads() as u64).clamp(1, tasks.max(1));
        // A strip's sums are many rows of a strip's width, which the
        // allocator keeps in the thread's heaps.
        let strip = crate::memory::in_heaps(self.strip_bytes(self.kernel(unit), w, holes));
        lists.saturating_add(running.saturating_mul(strip))
    }

    /// The bytes one strip of `w` columns holds while `kernel` fits it.
    fn strip_bytes(&self, kernel: Kernel, w: u64, holes: bool) -> u64 {
        let n = self.n as u64;
        // A row's heights with their borders, w + 2r (grown in up to
        // three steps: at most twice that).
        let padded = 2 * (w + n);
        // A row's sums: three planes and its padded heights, and `extra`.
        let row = |extra: u64| 8 * (3 * w + padded) + extra;
        // The window sums: four planes, and which patches hold a hole.
        let window = 32 * w + if holes { w } else { 0 };
        let sums = match kernel {
            // A ring of N rows' sums, and the row entering.
            Kernel::Sliding => (n + 1) * row(0) + window,
            // N rows' sums and their squares.
            Kernel::Direct => n * row(8 * padded) + window,
            // 2N rows' sums, each with a block's suffixes and prefixes (N
            // of 24 bytes each); the values of four blocks side by side and
            // their suffixes and prefixes (2N − 1 and 6N values a lane); N
            // suffixes of window sums, a prefix, the sums and a zero.
            Kernel::Blocked => 2 * n * row(48 * n) + 8 * BLOCK_LANES as u64 * 8 * n + (n + 3) * window,
            // N rows' sums and their squares; with holes, N rows' weighted
            // mask sums (three planes) and the six moments' planes.
            Kernel::Weighted => {
                let direct = n * row(8 * padded) + window + if holes { 24 * (n + 2) * w + padded } else { 0 };
                // By blocks, also a block's inputs (three planes of B + 2r
                // rows) and outputs (four of B), a block of one row's sums,
                // and the transforms' buffers (about 7 of L ≤ 1.5·B + 2r
                // complex values).
                direct
                    + self.blocks.as_ref().map_or(0, |b| {
                        let (len, r) = (b.len as u64, b.r as u64);
                        8 * w * (3 * (len + 2 * r) + 4 * len) + row(0) + 16 * 7 * (2 * len + 2 * r)
                    })
            }
        };
        // The normals' three planes; in map units, the unequal spacing's
        // matrices and Newton planes (about 160 bytes a column).
        let emit = 24 * w + if self.spacing.is_some() { 160 * w } else { 0 };
        // Holes: the mask's running sums and valid row (about 100 bytes a
        // column), the masked patches' moments and Newton planes (300).
        let mask = if holes { 400 * w + padded } else { 0 };
        sums + emit + mask
    }

    /// The holes of one strip: `None` when no row it reads holds one (every
    /// texel is then valid, and the strip is fitted as without holes).
    pub(super) fn strip_holes<'t, 'a, H: Sample>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        y0: usize,
        len: usize,
        cols: Range<usize>,
        valid: Option<(Vec<&'t mut [bool]>, f64)>,
    ) -> Option<StripHoles<'t>> {
        let (mut valid, nodata) = valid?;
        let r = self.r as isize;
        if !(y0 as isize - r..(y0 + len) as isize + r).any(|v| rows(v).holes) {
            valid.iter_mut().for_each(|row| row.fill(true));
            return None;
        }
        let weighted = (self.weights != Weights::Uniform).then(|| super::masked::WeightedMask::new(self, cols.clone()));
        Some(StripHoles { mask: MaskSums::new(cols), patches: MaskedRow::default(), valid, nodata, weighted })
    }

    /// Makes the valid points' sums those of output row `y`, and marks in
    /// `v` the patches that hold a hole, before [`Self::emit`].
    pub(super) fn advance_holes<'a, H: Sample>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        y: usize,
        holes: &mut StripHoles<'_>,
        v: &mut WindowSums,
    ) {
        holes.mask.advance(self, rows, y as isize, holes.nodata);
        if let Some(weighted) = holes.weighted.as_mut() {
            weighted.advance(self, rows, y as isize, holes.nodata);
        }
        let n2 = (self.n * self.n) as i64;
        v.with_hole.clear();
        v.with_hole.extend(holes.mask.c.iter().map(|&c| c != n2));
    }

    /// Output row `y` (row `k` of the strip) from its window sums `v`, as
    /// every kernel ends a row: with holes the valid points' sums made
    /// first ([`Self::advance_holes`]), then [`Self::emit`] and the
    /// residual, then the patches that hold a hole refitted
    /// ([`Self::patch_holes`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn finish_row<'a, H: Sample, T: Texel>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        v: &mut WindowSums,
        gain: f64,
        (y, k): (usize, usize),
        mut holes: Option<&mut StripHoles<'_>>,
        scratch: &mut EmitScratch,
        out: &mut [T],
        mut residual: Option<&mut [f32]>,
    ) {
        if let Some(holes) = holes.as_deref_mut() {
            self.advance_holes(rows, y, holes, v);
        }
        self.emit(v, gain, y, scratch, out);
        if let Some(residual) = residual.as_deref_mut() {
            self.emit_residual(v, gain, y, scratch, residual);
        }
        if let Some(holes) = holes {
            self.patch_holes(v, gain, (y, k), holes, out, residual);
        }
    }

    /// Refits the texels of output row `y` (row `k` of the strip) whose
    /// patch has a hole, from the valid points' moments (see `masked`;
    /// [`Self::advance_holes`] made them), over what [`Self::emit`] wrote,
    /// and marks the missing ones. `v` and `gain` are as `emit` took them.
    pub(super) fn patch_holes<T: Texel>(
        &self,
        v: &WindowSums,
        gain: f64,
        (y, k): (usize, usize),
        holes: &mut StripHoles<'_>,
        out: &mut [T],
        residual: Option<&mut [f32]>,
    ) {
        let StripHoles { mask, patches, valid, weighted, .. } = holes;
        let valid = &mut valid[k];
        valid.fill(true);
        let n2 = (self.n * self.n) as i64;
        if mask.full(n2) {
            return;
        }
        let ([sx, _], rho) = self.spacing_at(y);
        let g = gain / sx;
        patches.clear(out.len());
        for x in (0..out.len()).filter(|&x| mask.c[x] != n2) {
            let moments = Moments {
                c: mask.c[x],
                geometry: [mask.si[x], mask.sj[x], mask.sii[x], mask.sjj[x], mask.sij[x]],
                z: [g * v.s0[x], g * v.si[x], g * v.sj[x], g * g * v.szz[x]],
                weighted: weighted.as_ref().map(|m| m.at(x)),
            };
            patches.push(x, mask.centre[x], &moments);
        }
        patches.solve(self.fit == Fit::Orthogonal, rho, self.sigma);
        patches.store(out, valid, residual, sx, (&self.frame, T::make(self.missing, &self.frame)));
    }

    /// The source row of padded row p = y + j + r, through the y border.
    #[inline]
    pub(super) fn source_y(&self, p: usize) -> usize {
        self.borders.y.map(p as isize - self.r as isize, self.height)
    }

    /// Columns per parallel task: about 512, and at least 8·N, so that
    /// starting a strip's sums (N steps a row) costs at most an eighth of
    /// the strip's work.
    pub(super) fn strip_cols(&self) -> usize {
        // The weighted sums have no start-up cost to spread: a strip of
        // ~512 columns keeps their N rows small at any N.
        // By blocks, strips of whole blocks (from column 0), so that none
        // is made twice.
        if let Some(blocks) = &self.blocks {
            return STRIP_COLS.div_ceil(blocks.len) * blocks.len;
        }
        if self.weights != Weights::Uniform {
            return STRIP_COLS;
        }
        STRIP_COLS.max(8 * self.n)
    }

    /// The heights of columns `lo .. hi` of `src`, times `gain`, into
    /// `padded`: those that `src` holds as they are, the others through
    /// the x border (which the caller made sure maps them into `src`).
    #[inline(always)]
    pub(super) fn padded_row<H: Sample>(
        &self,
        src: RowRef<'_, H>,
        (lo, hi): (isize, isize),
        gain: f64,
        padded: &mut Vec<f64>,
    ) {
        padded.clear();
        let (a, b) = (lo - src.x0, hi - src.x0);
        if src.holes {
            // A hole adds nothing to the z sums (see `masked`).
            let nodata = self.nodata.unwrap_or(f64::NAN);
            let value = |u: isize| {
                let at = if (src.x0..src.x0 + src.values.len() as isize).contains(&u) {
                    u
                } else {
                    self.borders.x.map(u, self.width) as isize
                };
                let h = src.values[(at - src.x0) as usize].to_f64();
                if super::masked::is_hole(h, nodata) { 0.0 } else { gain * h }
            };
            if a >= 0 && b <= src.values.len() as isize {
                let values = &src.values[a as usize..b as usize];
                padded.extend(values.iter().map(|&h| {
                    let h = h.to_f64();
                    if super::masked::is_hole(h, nodata) { 0.0 } else { gain * h }
                }));
            } else {
                padded.extend((lo..hi).map(value));
            }
        } else {
            // The columns `src` holds in the same vectorised loop as away
            // from the borders (out of line, a row's first and last strips
            // had converted them in a loop compiled for baseline x86-64:
            // 9 % of a 1024² fit's instructions), those beyond out of line.
            let held = src.x0..src.x0 + src.values.len() as isize;
            let (inside_lo, inside_hi) = (lo.max(held.start).min(hi), hi.min(held.end).max(lo));
            self.bordered_values(src, lo..inside_lo, gain, padded);
            let inside = &src.values[(inside_lo - src.x0) as usize..(inside_hi - src.x0) as usize];
            padded.extend(inside.iter().map(|&h| gain * h.to_f64()));
            self.bordered_values(src, inside_hi..hi, gain, padded);
        }
    }

    /// The heights of columns `cols` of a row beyond what `src` holds,
    /// times `gain`, through the x border (which maps them into `src`),
    /// appended to `padded`. Out of line: a few columns of a row's first
    /// and last strips, and the hot loop stays small.
    #[inline(never)]
    pub(super) fn bordered_values<H: Sample>(
        &self,
        src: RowRef<'_, H>,
        cols: Range<isize>,
        gain: f64,
        padded: &mut Vec<f64>,
    ) {
        let held = src.x0..src.x0 + src.values.len() as isize;
        padded.extend(cols.map(|u| {
            let at = if held.contains(&u) { u } else { self.borders.x.map(u, self.width) as isize };
            gain * src.values[(at - src.x0) as usize].to_f64()
        }));
    }

    /// Fits one strip of stored integers by running sums. Sums of the
    /// integers themselves are exact in f64 (below 2^53 for 16 bits and
    /// N ≤ 63), so adding the entering texel and removing the leaving one
    /// gives every texel exactly the sums of its own patch, wherever the
    /// run started; the gain comes after, in the normals.
    #[inline(always)]
    pub(super) fn fit_strip_sliding<'a, H: Sample, T: Texel>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let n = self.n;
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let row_of = |p: usize| rows(p as isize - self.r as isize);
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);

        // Ring of the N rows' horizontal sums: slot p % N holds padded row p.
        let mut ring: Vec<RowSums> = (y0..y0 + n)
            .map(|p| {
                let mut sums = RowSums::zeros(w);
                self.sliding_row_sums(row_of(p), cols.clone(), &mut sums);
                sums
            })
            .collect();
        ring.rotate_right(y0 % n);
        let mut entering = RowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);

        let mut v = WindowSums::zeros(w);
        for j in 0..n {
            v.add(&ring[(y0 + j) % n], j as f64 - self.r as f64);
        }

        let (rf, r1) = (self.r as f64, self.r as f64 + 1.0);
        for (k, out_row) in out.iter_mut().enumerate() {
            if k > 0 {
                // Slide down one row: padded row p_in enters, p_out leaves.
                let p_out = y0 + k - 1;
                let p_in = p_out + n;
                self.sliding_row_sums(row_of(p_in), cols.clone(), &mut entering);
                v.slide(&ring[p_out % n], &entering, rf, r1);
                std::mem::swap(&mut ring[p_out % n], &mut entering);
            }
            let residual = residual.as_mut().map(|r| &mut *r[k]);
            self.finish_row(rows, &mut v, gain, (y0 + k, k), holes.as_mut(), &mut scratch, out_row, residual);
        }
    }

    /// Σh, Σih, Σh² over each column's horizontal window of one source row
    /// of integers, by a running sum along the strip.
    #[inline(always)]
    pub(super) fn sliding_row_sums<H: Sample>(&self, src: RowRef<'_, H>, cols: Range<usize>, out: &mut RowSums) {
        // Disjoint borrows, and below slices of the strip's length: the
        // sliding loop then keeps every pointer in a register and has no
        // bounds checks (through `out`, it reloaded the planes' pointers
        // and lengths at every texel, 17 % more instructions).
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, .. } = out;
        let (n, r) = (self.n, self.r);
        let (rf, r1) = (r as f64, r as f64 + 1.0);
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), 1.0, padded);
        let (mut s0, mut si, mut szz) = (0.0, 0.0, 0.0);
        for (q, &z) in padded[..n].iter().enumerate() {
            s0 += z;
            si += (q as f64 - rf) * z;
            szz += z * z;
        }
        let (out_s0, out_si, out_szz) = (&mut out_s0[..w], &mut out_si[..w], &mut out_szz[..w]);
        out_s0[0] = s0;
        out_si[0] = si;
        out_szz[0] = szz;
        // Texel k (k ≥ 1): padded[k − 1] leaves the window, padded[k − 1 + n] enters it.
        let slides = padded.iter().zip(&padded[n..]);
        let outs = out_s0[1..].iter_mut().zip(&mut out_si[1..]).zip(&mut out_szz[1..]);
        for ((&leaving, &entering), ((o0, oi), ozz)) in slides.zip(outs) {
            s0 += entering - leaving;
            si += rf * leaving + r1 * entering - s0;
            szz += entering * entering - leaving * leaving;
            *o0 = s0;
            *oi = si;
            *ozz = szz;
        }
    }

    /// Fits one strip with a small patch (floats, N ≤ 7; stored integers,
    /// N = 3) by summing each texel's patch outright, its values in order
    /// along the row and then its rows in order: a texel's sums are made
    /// from its patch alone, the same bits in whatever strip, tile or
    /// window it is computed. At this size the sums take no more work than
    /// running sums, and the loops run across the columns, so they
    /// vectorise. The heights are summed times the first of `gains` (the
    /// gain for floats, 1 for stored integers) and the normals made with
    /// the second (1, or the gain), as [`Self::fit_strip_sliding`] makes
    /// them for stored integers.
    #[inline(always)]
    pub(super) fn fit_strip_direct<'a, H: Sample, T: Texel, const N: usize>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        (gain, emit_gain): (f64, f64),
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let r = (N / 2) as isize;
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);
        // Beyond N = 5 the chunks' N rows of slices cost more than the
        // planes they save (N = 7, vertical: 1.07–1.11× the time, measured).
        let fused = N <= 5 && self.fuses(holes.is_some(), residual.is_some());
        let mut cache = RowCache::new(N, w);
        let mut v = WindowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);
        for (k, out_row) in out.iter_mut().enumerate() {
            let y = (y0 + k) as isize;
            for u in y - r..=y + r {
                if let Some(sums) = cache.stale(u) {
                    self.direct_row_sums::<H, N>(rows(u), gain, cols.clone(), sums);
                }
            }
            let patch_rows: [&RowSums; N] = std::array::from_fn(|j| cache.held(y - r + j as isize));
            if fused && self.fuses_row(y0 + k) {
                match self.fit {
                    Fit::Orthogonal => {
                        self.emit_fused::<T, N, true>(&patch_rows, (y0 + k, emit_gain), &mut scratch, out_row)
                    }
                    Fit::Vertical => {
                        self.emit_fused::<T, N, false>(&patch_rows, (y0 + k, emit_gain), &mut scratch, out_row)
                    }
                }
                continue;
            }
            v.sum_rows(&patch_rows);
            let residual = residual.as_mut().map(|r| &mut *r[k]);
            self.finish_row(rows, &mut v, emit_gain, (y0 + k, k), holes.as_mut(), &mut scratch, out_row, residual);
        }
    }

    /// Whether a strip's rows go from the row sums to the texels in one
    /// pass ([`Self::emit_fused`]): no plane of window sums that something
    /// else reads (holes, the residual, the moments' texels).
    fn fuses(&self, holes: bool, residual: bool) -> bool {
        !holes && !residual && !self.moments
    }

    /// Whether output row `y` of a strip that [`Self::fuses`] does: every
    /// row but those of the orthogonal fit where the spacing is unequal,
    /// whose Newton steps over chunks of 32 (each chunk's slow patches
    /// moved together on their own) took longer than over the strip's
    /// planes (`examples/core_speed.rs --geographic`: 1.03–1.16× the time
    /// at N = 3, measured turn about).
    fn fuses_row(&self, y: usize) -> bool {
        self.fit == Fit::Vertical || self.spacing_at(y).1 == 1.0
    }

    /// Output row `y` from its patch's row sums, straight to the texels:
    /// [`WindowSums::sum_rows`], [`Self::emit`] and
    /// [`store_normals`](super::emit::store_normals) chunk by chunk, each
    /// chunk's sums and normals in arrays that stay in the core's first
    /// cache rather than in planes the width of the strip. The same
    /// operations in the same order: the same bits.
    #[inline(always)]
    fn emit_fused<T: Texel, const N: usize, const ORTHOGONAL: bool>(
        &self,
        rows: &[&RowSums; N],
        (y, gain): (usize, f64),
        scratch: &mut EmitScratch,
        out: &mut [T],
    ) {
        const C: usize = EMIT_CHUNK;
        let w = out.len();
        // The rows' sums are in units of z / `gain` (stored integers) or
        // of z (`gain` 1: the gain went in with the heights), lengths in
        // units of the x spacing, as `emit` takes them.
        let ([sx, _], rho) = self.spacing_at(y);
        let gain = gain / sx;
        let frame = self.frame;
        // The chunks' arrays, made once a row: zeroed in every chunk (2 KiB
        // of stores per 32 texels), they took 4 % of the N = 3 fit's
        // instructions (callgrind, `examples/core_speed.rs`).
        let (mut s0, mut si, mut sj, mut szz) = ([0.0; C], [0.0; C], [0.0; C], [0.0; C]);
        let (mut nx, mut ny, mut nz, mut czz) = ([0.0; C], [0.0; C], [0.0; C], [0.0; C]);
        for (start, out) in (0..w).step_by(C).zip(out.chunks_mut(C)) {
            let len = out.len();
            let (s0, si, sj, szz) = (&mut s0[..len], &mut si[..len], &mut sj[..len], &mut szz[..len]);
            patch_sums(rows, start..start + len, [&mut *s0, &mut *si, &mut *sj, &mut *szz]);
            let sums = [&*s0, &*si, &*sj, &*szz];
            let normal = [&mut nx[..len], &mut ny[..len], &mut nz[..len]];
            if rho == 1.0 {
                self.square_chunk::<ORTHOGONAL>(gain, sums, None, T::UNIT, normal, &mut czz);
            } else {
                let row = RowSpacing { gain, rho, orthogonal: ORTHOGONAL };
                scratch.unequal.fill_normals(self, sums, row, normal);
            }
            for (((texel, &x), &y), &z) in out.iter_mut().zip(&nx[..len]).zip(&ny[..len]).zip(&nz[..len]) {
                *texel = T::make([x, y, z], &frame);
            }
        }
    }

    /// Σz, Σiz, Σz² (z = gain · h) over each column's horizontal window of
    /// one source row, each window summed outright (see
    /// [`Self::fit_strip_direct`]).
    #[inline(always)]
    pub(super) fn direct_row_sums<H: Sample, const N: usize>(
        &self,
        src: RowRef<'_, H>,
        gain: f64,
        cols: Range<usize>,
        out: &mut RowSums,
    ) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, squares, .. } = out;
        let r = N / 2;
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        // Σiz pairs the texels at ±d: Σ d·(z[r + d] − z[r − d]).
        squares.clear();
        squares.extend(padded.iter().map(|z| z * z));
        let outs = out_s0[..w].iter_mut().zip(&mut out_si[..w]).zip(&mut out_szz[..w]);
        for ((window, squares), ((o0, oi), ozz)) in padded.windows(N).zip(squares.windows(N)).zip(outs) {
            let z: &[f64; N] = window.try_into().expect("windows of N");
            let zz: &[f64; N] = squares.try_into().expect("windows of N");
            let (mut s0, mut si, mut szz) = (z[0], z[r + 1] - z[r - 1], zz[0]);
            for q in 1..N {
                s0 += z[q];
                szz += zz[q];
            }
            for d in 2..=r {
                si += d as f64 * (z[r + d] - z[r - d]);
            }
            *o0 = s0;
            *oi = si;
            *ozz = szz;
        }
    }

    /// Fits one strip of floats by sums over blocks aligned on the image
    /// (van Herk, Gil–Werman). Output texel t of block k (x = kN + t,
    /// 0 ≤ t < N) has the window [x − r, x + r]: the suffix of the values
    /// [kN − r, kN + r] from x − r, plus the prefix of the next N values up
    /// to x + r (empty for t = 0). Each is summed in a fixed order from
    /// values of the patch alone, across and then down, so a texel's sums
    /// are the same bits in whatever strip, tile or window it is computed
    /// (running sums of floats would carry the rounding of wherever they
    /// started); the cost per texel stays flat in N.
    #[inline(always)]
    pub(super) fn fit_strip_blocked<'a, H: Sample, T: Texel>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let (n, r) = (self.n, self.r as isize);
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let y_end = y0 + out.len();
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);

        // Horizontal sums of the source rows a block of output rows and
        // the next one read (2N rows), in slot v mod 2N.
        let mut cache = RowCache::new(2 * n, w);
        let mut lanes = BlockLanes::default();
        let mut suffix: Vec<WindowSums> = (0..n).map(|_| WindowSums::zeros(w)).collect();
        let (zero, mut prefix, mut v) = (WindowSums::zeros(w), WindowSums::zeros(w), WindowSums::zeros(w));
        let mut scratch = EmitScratch::new(w);

        for block in y0 / n..=(y_end - 1) / n {
            let top = (block * n) as isize;
            let ts = y0.saturating_sub(block * n)..(y_end - block * n).min(n);
            // Weights j relative to o = top + r + 1, the next block's first
            // source row; output row t's own offsets are j − (t − r − 1).
            let o = top + r + 1;
            // Suffixes, in place: suffix[t] = suffix[t + 1] + row top + t − r
            // (rows top + r down to top + t − r, the last alone).
            for t in (ts.start..n).rev() {
                let u = top + t as isize - r;
                let h = self.blocked_row((&mut cache, &mut lanes), rows, u, gain, &cols);
                let (lower, upper) = suffix.split_at_mut(t + 1);
                let previous = upper.first().unwrap_or(&zero);
                lower[t].set_sum(previous, h, (u - o) as f64);
            }
            // Prefixes: rows top + r + 1 up to top + r + t; the row that
            // completes one goes in with the combination, in one pass.
            prefix.clear();
            let mut through = top + r;
            for t in ts.clone() {
                let shift = (t as isize - r - 1) as f64;
                let wanted = top + r + t as isize;
                while through + 1 < wanted {
                    through += 1;
                    prefix.add(
                        self.blocked_row((&mut cache, &mut lanes), rows, through, gain, &cols),
                        (through - o) as f64,
                    );
                }
                if through < wanted {
                    through += 1;
                    prefix.add_then_combine(
                        self.blocked_row((&mut cache, &mut lanes), rows, through, gain, &cols),
                        (through - o) as f64,
                        &suffix[t],
                        shift,
                        &mut v,
                    );
                } else {
                    v.combine(&suffix[t], &prefix, shift);
                }
                let k = block * n + t - y0;
                let residual = residual.as_mut().map(|r| &mut *r[k]);
                self.finish_row(rows, &mut v, 1.0, (y0 + k, k), holes.as_mut(), &mut scratch, out[k], residual);
            }
        }
    }

    /// Source row v's sums in `cache`, made now unless it holds them:
    /// compiled, on their own, for the widest vectors the processor has
    /// (inside the strip's loop, three copies of them made its registers
    /// spill; in a closure, they were compiled for baseline x86-64).
    #[inline(always)]
    fn blocked_row<'c, H: Sample>(
        &self,
        (cache, lanes): (&'c mut RowCache, &mut BlockLanes),
        rows: &SourceRows<'_, '_, H>,
        v: isize,
        gain: f64,
        cols: &Range<usize>,
    ) -> &'c RowSums {
        if let Some(sums) = cache.stale(v) {
            let (plan, src, cols) = (self, rows(v), cols.clone());
            pulp::Arch::new().dispatch(BlockedRow { plan, src, gain, cols, sums, lanes });
        }
        cache.held(v)
    }

    /// Σz, Σiz, Σz² (z = gain · h) over each column's horizontal window of
    /// one source row, from block-aligned suffix and prefix sums (see
    /// [`Self::fit_strip_blocked`]).
    #[inline(always)]
    pub(super) fn blocked_row_sums<H: Sample>(
        &self,
        src: RowRef<'_, H>,
        gain: f64,
        cols: Range<usize>,
        out: &mut RowSums,
        lanes: &mut BlockLanes,
    ) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, suffix, prefix, .. } = out;
        let (n, r) = (self.n, self.r);
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        // Weights relative to the next block's first value (q = 2r + 1).
        let weight = |q: usize| q as f64 - (2 * r + 1) as f64;
        suffix.resize(n, [0.0; 3]);
        prefix.resize(n, [0.0; 3]);
        let last = (cols.end - 1) / n;
        // Whether every column of a block is in `cols` (all but perhaps the
        // first and the last are).
        let whole = |block: usize| block * n >= cols.start && (block + 1) * n <= cols.end;
        let mut block = cols.start / n;
        while block <= last {
            let bx = block * n;
            if block + BLOCK_LANES - 1 <= last && whole(block) && whole(block + BLOCK_LANES - 1) {
                let blocks = bx - cols.start..bx - cols.start + BLOCK_LANES * n;
                lanes.side_by_side(n, weight, &padded[blocks.start..], |l, t, [h0, hi, hzz]| {
                    let x = blocks.start + l * n + t;
                    out_s0[x] = h0;
                    out_si[x] = hi - (t as f64 - r as f64 - 1.0) * h0;
                    out_szz[x] = hzz;
                });
                block += BLOCK_LANES;
                continue;
            }
            let ts = cols.start.saturating_sub(bx)..(cols.end - bx).min(n);
            // Value q of the block (column bx − r + q) is padded[bx + q − cols.start].
            let z = &padded[bx + ts.start - cols.start..];
            let at = |q: usize| z[q - ts.start];
            // The suffixes (values q = 2r down to t) and the prefixes
            // (values q = 2r + 1 up to 2r + t) in one loop while both run:
            // six chains of additions side by side rather than three.
            let (suffix_steps, prefix_steps) = (n - ts.start, ts.end.saturating_sub(1));
            let (mut a0, mut ai, mut azz) = (0.0, 0.0, 0.0);
            let (mut p0, mut pi, mut pzz) = (0.0, 0.0, 0.0);
            let mut suffix_step = |i: usize| {
                let q = 2 * r - i;
                let zq = at(q);
                a0 += zq;
                ai += weight(q) * zq;
                azz += zq * zq;
                suffix[q] = [a0, ai, azz];
            };
            let mut prefix_step = |i: usize| {
                let q = 2 * r + 1 + i;
                let zq = at(q);
                p0 += zq;
                pi += weight(q) * zq;
                pzz += zq * zq;
                prefix[i + 1] = [p0, pi, pzz];
            };
            let both = suffix_steps.min(prefix_steps);
            for i in 0..both {
                suffix_step(i);
                prefix_step(i);
            }
            (both..suffix_steps).for_each(&mut suffix_step);
            (both..prefix_steps).for_each(&mut prefix_step);
            prefix[0] = [0.0; 3];
            for t in ts {
                let ([a0, ai, azz], [p0, pi, pzz]) = (suffix[t], prefix[t]);
                let h0 = a0 + p0;
                let x = bx + t - cols.start;
                out_s0[x] = h0;
                out_si[x] = (ai + pi) - (t as f64 - r as f64 - 1.0) * h0;
                out_szz[x] = azz + pzz;
            }
            block += 1;
        }
    }

    /// Turns the window sums of one row into normals, through `scratch`'s
    /// planes (x, y and z): the fit's loop then stores whole vectors, and
    /// the texel type's conversion is a loop of its own. The sums are in
    /// units of z / `gain` (stored integers), or of z (`gain` 1); `y` is
    /// the image row, whose spacing map units fit with.
    pub(super) fn emit<T: Texel>(&self, v: &WindowSums, gain: f64, y: usize, scratch: &mut EmitScratch, out: &mut [T]) {
        let normal = &mut scratch.normal;
        if self.moments {
            let n2 = self.count;
            let czz_gain = gain * gain / n2;
            let w = out.len();
            let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
            for (x, texel) in out.iter_mut().enumerate() {
                *texel = T::make([gain * si[x], gain * sj[x], Self::czz(n2, czz_gain, s0[x], szz[x])], &self.frame);
            }
            return;
        }
        // Lengths in units of the x spacing: z / sx, and ρ = sy / sx the
        // rows' spacing. In texel units, and for square pixels, ρ = 1 and
        // the contract's square-grid formulas run (sx = 1: the same bits).
        let ([sx, _], rho) = self.spacing_at(y);
        let gain = gain / sx;
        // One loop per fit, so the per-texel work has no branch and vectorises.
        match self.fit {
            Fit::Orthogonal if rho == 1.0 => {
                pulp::Arch::new().dispatch(EmitRow::<T, true> { plan: self, v, gain, normal, out })
            }
            Fit::Vertical if rho == 1.0 => {
                pulp::Arch::new().dispatch(EmitRow::<T, false> { plan: self, v, gain, normal, out })
            }
            fit => {
                let row = RowSpacing { gain, rho, orthogonal: fit == Fit::Orthogonal };
                scratch.unequal.normals(self, v, row, normal, out);
            }
        }
    }

    /// Czz = (N²·Σz² − (Σz)²) / N² times the gain², from one column's
    /// sums: for stored integers the numerator is exact (below 2^53 for
    /// 8 bits, and for 16 bits up to N = 37; beyond, A dwarfs its
    /// rounding), and it does not cancel as Σz² − (Σz)²/N² would.
    #[inline(always)]
    pub(super) fn czz(n2: f64, czz_gain: f64, s0: f64, szz: f64) -> f64 {
        ((n2 * szz - s0 * s0) * czz_gain).max(0.0)
    }

    /// The spacing `[sx, sy]` of image row `y` and ρ = sy / sx: `[1, 1]`
    /// and 1 in texel units.
    #[inline]
    pub(super) fn spacing_at(&self, y: usize) -> ([f64; 2], f64) {
        match &self.spacing {
            None => ([1.0, 1.0], 1.0),
            Some(spacing) => {
                let [sx, sy] = spacing.at(y);
                ([sx, sy], sy / sx)
            }
        }
    }

    #[inline(always)]
    pub(super) fn emit_with<const ORTHOGONAL: bool>(
        &self,
        v: &WindowSums,
        gain: f64,
        unit: bool,
        normal: &mut [Vec<f64>; 3],
    ) {
        let w = normal[0].len();
        let planes = v.planes(w);
        let mut czz = [0.0; EMIT_CHUNK];
        for start in (0..w).step_by(EMIT_CHUNK) {
            let texels = start..(start + EMIT_CHUNK).min(w);
            let sums = planes.map(|plane| &plane[texels.clone()]);
            let with_hole = (!v.with_hole.is_empty()).then(|| &v.with_hole[texels.clone()]);
            let chunk = normal.each_mut().map(|plane| &mut plane[texels.clone()]);
            self.square_chunk::<ORTHOGONAL>(gain, sums, with_hole, unit, chunk, &mut czz);
        }
    }

    /// The square grid's normals of at most [`EMIT_CHUNK`] texels from
    /// their window sums `[s0, si, sj, szz]` (in units of z / `gain`), into
    /// `[nx, ny, nz]`: a row's chunk ([`Self::emit_with`]) or the one-pass
    /// emit's ([`Self::emit_fused`]). `czz` is the caller's scratch.
    #[inline(always)]
    fn square_chunk<const ORTHOGONAL: bool>(
        &self,
        gain: f64,
        [s0, si, sj, szz]: [&[f64]; 4],
        with_hole: Option<&[bool]>,
        unit: bool,
        [nx, ny, nz]: [&mut [f64]; 3],
        czz: &mut [f64; EMIT_CHUNK],
    ) {
        let len = s0.len();
        let (si, sj, szz) = (&si[..len], &sj[..len], &szz[..len]);
        let (nx, ny, nz) = (&mut nx[..len], &mut ny[..len], &mut nz[..len]);
        let n2 = self.count;
        let czz_gain = gain * gain / n2;
        let (gx, gy) = (gain, self.sigma * gain);
        let czz = &mut czz[..len];
        czz.iter_mut().zip(s0).zip(szz).for_each(|((c, &a), &b)| *c = Self::czz(n2, czz_gain, a, b));
        // Only a patch whose heights spread more than its columns and
        // rows (Czz > A) needs the orthogonal fit's division; most
        // chunks have none, and their loop leaves it out (the
        // division took a tenth of the fit), with the same results.
        // A patch with a hole (read as 0: a cliff) is refitted after,
        // whatever this loop gives it, and does not make its chunk steep.
        let steep = ORTHOGONAL
            && match with_hole {
                None => czz.iter().any(|&c| c > self.a),
                Some(hole) => czz.iter().zip(&hole[..len]).any(|(&c, &hole)| c > self.a && !hole),
            };
        if steep {
            for x in 0..len {
                [nx[x], ny[x], nz[x]] =
                    normal_from_sums::<ORTHOGONAL, true>(self.a, gx * si[x], gy * sj[x], czz[x], unit);
            }
        } else {
            for x in 0..len {
                [nx[x], ny[x], nz[x]] =
                    normal_from_sums::<ORTHOGONAL, false>(self.a, gx * si[x], gy * sj[x], czz[x], unit);
            }
        }
    }

    /// The RMS distance of each texel's patch points from its fitted plane,
    /// in surface units, from the window sums of one row. A loop of its
    /// own, run only when asked for, so the normals' loop stays as it is.
    /// In map units, the distances are in the heights' unit (the fit's
    /// lengths in x spacings, times sx).
    pub(super) fn emit_residual(
        &self,
        v: &WindowSums,
        gain: f64,
        y: usize,
        scratch: &mut EmitScratch,
        out: &mut [f32],
    ) {
        let ([sx, _], rho) = self.spacing_at(y);
        let gain = gain / sx;
        match self.fit {
            // The vertical fit's residual does not depend on ρ: ordinary
            // least squares leaves the same residual however its regressors
            // are scaled. The orthogonal fit's is the smallest eigenvalue
            // of the scatter matrix.
            Fit::Orthogonal if rho != 1.0 => {
                scratch.unequal.residuals(self, v, RowSpacing { gain, rho, orthogonal: true }, sx, out)
            }
            Fit::Orthogonal => self.emit_residual_with::<true>(v, gain, sx, out),
            Fit::Vertical => self.emit_residual_with::<false>(v, gain, sx, out),
        }
    }

    pub(super) fn emit_residual_with<const ORTHOGONAL: bool>(
        &self,
        v: &WindowSums,
        gain: f64,
        sx: f64,
        out: &mut [f32],
    ) {
        let n2 = self.count;
        let (inv_n2, czz_gain) = (1.0 / n2, gain * gain / n2);
        let w = out.len();
        let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
        for x in 0..w {
            let czz = Self::czz(n2, czz_gain, s0[x], szz[x]);
            let sum = squared_distance_sum::<ORTHOGONAL>(self.a, gain * si[x], gain * sj[x], czz);
            out[x] = ((sum * inv_n2).sqrt() * sx) as f32;
        }
    }
}

/// [`Plan::blocked_row_sums`] of one source row, dispatched for the
/// processor's instruction set.
struct BlockedRow<'a, 'r, H> {
    plan: &'a Plan,
    src: RowRef<'r, H>,
    gain: f64,
    cols: Range<usize>,
    sums: &'a mut RowSums,
    lanes: &'a mut BlockLanes,
}

impl<H: Sample> pulp::WithSimd for BlockedRow<'_, '_, H> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        // Inlined here, so that it is compiled for each instruction set.
        let BlockedRow { plan, src, gain, cols, sums, lanes } = self;
        plan.blocked_row_sums(src, gain, cols, sums, lanes);
    }
}

/// [`Plan::emit_with`] and the texels' conversion, for
/// [`pulp::Arch::dispatch`]: compiled for the widest vectors the processor
/// has (AVX2 where baseline x86-64 has SSE2's two lanes of f64), chosen at
/// run time. The square roots and divisions were a fifth of a lit view's
/// processor time. They, and the other operations, round alike in every
/// instruction set, and nothing fuses a multiply with an add: the same
/// bits on every processor.
struct EmitRow<'a, T, const ORTHOGONAL: bool> {
    plan: &'a Plan,
    v: &'a WindowSums,
    gain: f64,
    normal: &'a mut [Vec<f64>; 3],
    out: &'a mut [T],
}

impl<T: Texel, const ORTHOGONAL: bool> pulp::WithSimd for EmitRow<'_, T, ORTHOGONAL> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        // Inlined here, so that it is compiled for each instruction set.
        let EmitRow { plan, v, gain, normal, out } = self;
        plan.emit_with::<ORTHOGONAL>(v, gain, T::UNIT, normal);
        store_normals(normal, &plan.frame, out);
    }
}
