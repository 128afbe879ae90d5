//! Data parallelism with the `parallel` feature, the same code serially
//! without it.
//!
//! Call sites import [`prelude`] instead of `rayon::prelude` and write
//! `par_chunks_mut`, `par_iter`, `par_iter_mut`, `into_par_iter`, `par_extend` as usual.
//! With `parallel` (the default) these are rayon's; without it they are
//! traits of the same names that hand back the standard library's serial
//! iterators (`chunks_mut`, `iter`, `into_iter`, `extend`), whose `map`,
//! `zip`, `enumerate` and `for_each` mean what rayon's do. What has no
//! same-named serial twin (rayon's `fold` and `reduce` take closures where
//! `Iterator`'s take values) is a function here ([`fold_reduce`]).
//!
//! The results are the same bits either way: the library's promise that
//! they do not depend on the number of threads (tests/integration/fit_reference.rs
//! runs pools of 1 to 8) covers the build without threads too, and CI
//! runs the reference tests in that build.

#[cfg(feature = "parallel")]
pub(crate) mod prelude {
    pub(crate) use rayon::prelude::*;
}

#[cfg(not(feature = "parallel"))]
pub(crate) mod prelude {
    //! Serial twins of the rayon methods the crate calls.

    use std::slice::{Chunks, ChunksExact, ChunksMut, Iter, IterMut};

    /// rayon's bound on "an iterator of items", serially any iterator.
    pub(crate) use std::iter::Iterator as ParallelIterator;

    /// `into_par_iter`: `into_iter`.
    pub(crate) trait IntoParallelIterator: IntoIterator + Sized {
        fn into_par_iter(self) -> Self::IntoIter {
            self.into_iter()
        }
    }

    impl<I: IntoIterator> IntoParallelIterator for I {}

    /// `par_iter`, `par_chunks`, `par_chunks_exact` on slices (and so on
    /// vectors).
    pub(crate) trait ParallelSlice<T> {
        fn par_iter(&self) -> Iter<'_, T>;
        fn par_chunks(&self, size: usize) -> Chunks<'_, T>;
        fn par_chunks_exact(&self, size: usize) -> ChunksExact<'_, T>;
    }

    impl<T> ParallelSlice<T> for [T] {
        fn par_iter(&self) -> Iter<'_, T> {
            self.iter()
        }
        fn par_chunks(&self, size: usize) -> Chunks<'_, T> {
            self.chunks(size)
        }
        fn par_chunks_exact(&self, size: usize) -> ChunksExact<'_, T> {
            self.chunks_exact(size)
        }
    }

    /// `par_chunks_mut` and `par_iter_mut` on slices.
    pub(crate) trait ParallelSliceMut<T> {
        fn par_chunks_mut(&mut self, size: usize) -> ChunksMut<'_, T>;
        fn par_iter_mut(&mut self) -> IterMut<'_, T>;
    }

    impl<T> ParallelSliceMut<T> for [T] {
        fn par_chunks_mut(&mut self, size: usize) -> ChunksMut<'_, T> {
            self.chunks_mut(size)
        }
        fn par_iter_mut(&mut self) -> IterMut<'_, T> {
            self.iter_mut()
        }
    }

    /// `par_extend` on vectors.
    pub(crate) trait ParallelExtend<T> {
        fn par_extend<I: IntoIterator<Item = T>>(&mut self, items: I);
    }

    impl<T> ParallelExtend<T> for Vec<T> {
        fn par_extend<I: IntoIterator<Item = T>>(&mut self, items: I) {
            self.extend(items);
        }
    }
}

/// The number of threads work is spread over: rayon's current pool's, or
/// 1 without the `parallel` feature. Sizes blocks and memory estimates,
/// never results.
#[must_use]
pub(crate) fn current_num_threads() -> usize {
    #[cfg(feature = "parallel")]
    return rayon::current_num_threads();
    #[cfg(not(feature = "parallel"))]
    1
}

/// rayon's `items.fold(identity, fold).reduce(identity, reduce)`: each
/// thread folds the items it takes into an accumulator started from
/// `identity()`, and the accumulators are combined by `reduce`. Serially,
/// one accumulator folds every item in order. Callers make `reduce`'s
/// result independent of how items were grouped (the tiling profiles add
/// exactly representable values), so both give the same bits.
#[cfg(feature = "parallel")]
pub(crate) fn fold_reduce<T: Send, A: Send>(
    items: impl prelude::ParallelIterator<Item = T>,
    identity: impl Fn() -> A + Sync + Send,
    fold: impl Fn(A, T) -> A + Sync + Send,
    reduce: impl Fn(A, A) -> A + Sync + Send,
) -> A {
    use prelude::ParallelIterator as _;
    items.fold(&identity, fold).reduce(&identity, reduce)
}

/// rayon's `items.fold(identity, fold).reduce(identity, reduce)`: each
/// thread folds the items it takes into an accumulator started from
/// `identity()`, and the accumulators are combined by `reduce`. Serially,
/// one accumulator folds every item in order. Callers make `reduce`'s
/// result independent of how items were grouped (the tiling profiles add
/// exactly representable values), so both give the same bits.
#[cfg(not(feature = "parallel"))]
pub(crate) fn fold_reduce<T, A>(
    items: impl Iterator<Item = T>,
    identity: impl Fn() -> A,
    fold: impl Fn(A, T) -> A,
    _reduce: impl Fn(A, A) -> A,
) -> A {
    items.fold(identity(), fold)
}
