//! Weighted sums by FFT in blocks aligned on the image: what makes
//! [`Weights::Binomial`](crate::Weights::Binomial) cost O(log N) a texel an
//! axis past [`FFT_FROM`].
//!
//! Binomial sums have no O(1) running form (the weights are (1 + x)^(N−1),
//! not a box), so along an axis the output texels are cut into blocks of
//! [`Blocks::len`] texels chosen from N alone ([`block_len`]), at
//! places fixed by the image ([`Blocks::start_of`]: along x from column 0;
//! along y the top r rows, then from row r, so that the fit's tiles and a
//! streaming caller's bands are whole blocks). A block of outputs
//! [s, e) is made from exactly the inputs [s − r, e + r) (through the
//! border), by one real FFT of a fixed length L ≥ e − s + 2r per input
//! plane and one inverse per output. A texel's sums are then the same bits
//! in whatever strip, tile, band, thread or window holds it, as long as the
//! window holds its whole block's inputs: [`super::HaloPlan`] plans that
//! halo and [`super::Window`] refuses a smaller one.
//!
//! Precision: before the transform each block subtracts a reference, its
//! first input (canonical per block), and adds back what it contributes
//! (ref·Σw, and for the squares 2·ref·Σw·(z − ref) + ref²·Σw): a flat
//! block transforms zeros and gives exactly its flat sums, and the
//! transform's rounding scales with the relief within the block, not with
//! the heights (a DEM near 400 m loses no more than the direct sums). A
//! block of a row whose inputs hold a hole is summed directly, so a hole
//! keeps reading 0 in the z sums exactly as in `super::weighted`.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use crate::options::Weights;

/// The smallest N whose binomial sums are made by FFT: below it the direct
/// sums (2·N multiply-adds a texel a plane) cost less than the transforms
/// (measured with bench/weights.sh on a 4096² DEM: by FFT 2.13 s of user
/// time at N = 33 against 2.01 outright, 2.26 against 2.46 at N = 41). N = 3, Horn's, always keeps its direct
/// sums, and so its bits.
pub(crate) const FFT_FROM: usize = 37;

/// The block length B for binomial weights at patch size `n`, or `None`
/// when the sums are made directly: L − 2r for the transform length L, the
/// power of two ≥ 6r, so that a block's B + 2r inputs fill the transform
/// and the 2r inputs shared with its neighbours are at most a third of it
/// (L·log L / B, the work an output, is near its least there).
pub(crate) fn block_len(weights: Weights, n: usize) -> Option<usize> {
    let r = n / 2;
    (weights == Weights::Binomial && n >= FFT_FROM).then(|| (6 * r).next_power_of_two() - 2 * r)
}

/// Where an axis's blocks lie: blocks of `len` from `first` on, and before
/// `first` one block of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Layout {
    pub(crate) len: usize,
    pub(crate) first: usize,
}

impl Layout {
    /// The first texel of the block holding texel `u`.
    pub(crate) fn start_of(&self, u: usize) -> usize {
        if u < self.first { 0 } else { self.first + (u - self.first) / self.len * self.len }
    }

    /// The end of the block starting at `start`, on an axis of `n`.
    pub(crate) fn end_of(&self, start: usize, n: usize) -> usize {
        if start < self.first { self.first.min(n) } else { (start + self.len).min(n) }
    }

    /// The texels [s, e) of the blocks holding texels `range` of an axis of
    /// `n` (non-empty).
    pub(crate) fn cover(&self, range: std::ops::Range<usize>, n: usize) -> (usize, usize) {
        let s = self.start_of(range.start);
        let last = self.start_of(range.end - 1);
        (s, self.end_of(last, n))
    }
}

/// One patch size's transforms: the kernels' spectra and the FFT plans.
pub(super) struct Blocks {
    /// B, the block length.
    pub(super) len: usize,
    /// r = N / 2.
    pub(super) r: usize,
    /// L, the transform's length.
    fft_len: usize,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    /// The conjugate spectra of w and w·u (a correlation), over L.
    w: Vec<Complex<f64>>,
    wu: Vec<Complex<f64>>,
    /// Σ w in the weights' order: what a reference contributes.
    pub(super) w_sum: f64,
}

impl std::fmt::Debug for Blocks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Blocks").field("len", &self.len).field("fft_len", &self.fft_len).finish()
    }
}

/// What which output takes: the kernel w or w·u.
#[derive(Clone, Copy)]
pub(super) enum Kernel {
    W,
    Wu,
}

/// One thread's buffers for [`Blocks`].
pub(super) struct Scratch {
    input: Vec<f64>,
    output: Vec<f64>,
    product: Vec<Complex<f64>>,
    fft: Vec<Complex<f64>>,
    /// Spectra of up to three inputs.
    pub(super) spectra: [Vec<Complex<f64>>; 3],
}

impl Blocks {
    /// The transforms of one axis's weights `w` and `wu` (w·u), blocks of
    /// `len`.
    pub(super) fn new(len: usize, w: &[f64], wu: &[f64]) -> Blocks {
        let n = w.len();
        let r = n / 2;
        let fft_len = (len + 2 * r).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let forward = planner.plan_fft_forward(fft_len);
        let inverse = planner.plan_fft_inverse(fft_len);
        let scale = 1.0 / fft_len as f64;
        let spectrum = |k: &[f64]| {
            let mut input = forward.make_input_vec();
            input[..n].copy_from_slice(k);
            let mut out = forward.make_output_vec();
            forward.process(&mut input, &mut out).expect("the buffers are the plan's own");
            out.iter().map(|c| c.conj() * scale).collect::<Vec<_>>()
        };
        let (ws, wus) = (spectrum(w), spectrum(wu));
        Blocks { len, r, fft_len, w: ws, wu: wus, w_sum: w.iter().sum(), forward, inverse }
    }

    pub(super) fn scratch(&self) -> Scratch {
        let len = self.forward.get_scratch_len().max(self.inverse.get_scratch_len());
        Scratch {
            input: self.forward.make_input_vec(),
            output: self.inverse.make_output_vec(),
            product: self.forward.make_output_vec(),
            fft: vec![Complex::default(); len],
            spectra: std::array::from_fn(|_| self.forward.make_output_vec()),
        }
    }

    /// The spectrum of `x` − `reference` (at most L values, zeros after)
    /// into spectrum `slot`; `square` transforms (x − reference)² instead.
    pub(super) fn transform(&self, x: &[f64], reference: f64, square: bool, slot: usize, s: &mut Scratch) {
        debug_assert!(x.len() <= self.fft_len);
        let (head, tail) = s.input.split_at_mut(x.len());
        if square {
            head.iter_mut().zip(x).for_each(|(o, &x)| *o = (x - reference) * (x - reference));
        } else {
            head.iter_mut().zip(x).for_each(|(o, &x)| *o = x - reference);
        }
        tail.fill(0.0);
        self.forward
            .process_with_scratch(&mut s.input, &mut s.spectra[slot], &mut s.fft)
            .expect("the buffers are the plan's own");
    }

    /// Σ k(q)·x(t + q), t = 0 … out.len() − 1, of spectrum `slot`'s input
    /// (x − ref), with `kernel`, into `out` (at most L − 2r values).
    pub(super) fn correlate(&self, slot: usize, kernel: Kernel, s: &mut Scratch, out: &mut [f64]) {
        debug_assert!(out.len() + 2 * self.r <= self.fft_len);
        let k = match kernel {
            Kernel::W => &self.w,
            Kernel::Wu => &self.wu,
        };
        s.product.iter_mut().zip(&s.spectra[slot]).zip(k).for_each(|((p, x), k)| *p = x * k);
        // A real signal's spectrum: DC and Nyquist are real (their
        // imaginary parts are ±0 here; the inverse requires it).
        let last = s.product.len() - 1;
        s.product[0].im = 0.0;
        s.product[last].im = 0.0;
        self.inverse
            .process_with_scratch(&mut s.product, &mut s.output, &mut s.fft)
            .expect("the buffers are the plan's own");
        out.copy_from_slice(&s.output[..out.len()]);
    }
}
