//! The 4 × 4 blocks of a level: how many, and which texel each place of a
//! block takes. A block past the level's right or bottom edge (levels
//! whose sides are not multiples of 4: 300 × 7, 2 × 2, 1 × 1) repeats the
//! edge texels, as texconv pads them, so a decoder's extra texels (which
//! the GPU never samples) cost the block's real texels no precision.

/// The blocks of a `width × height` level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct BlockGrid {
    /// Texels per row of the level.
    pub(crate) width: usize,
    /// Rows of the level.
    pub(crate) height: usize,
    /// Blocks per row: ⌈width / 4⌉.
    pub(crate) across: usize,
    /// Rows of blocks: ⌈height / 4⌉.
    pub(crate) down: usize,
}

impl BlockGrid {
    pub(crate) fn new(width: usize, height: usize) -> BlockGrid {
        BlockGrid { width, height, across: width.div_ceil(4), down: height.div_ceil(4) }
    }

    /// Column `x` (any, past the edge too) as a column of the level.
    #[inline]
    pub(crate) fn clamp_x(&self, x: usize) -> usize {
        x.min(self.width - 1)
    }

    /// Row `y` as a row of the level.
    #[inline]
    pub(crate) fn clamp_y(&self, y: usize) -> usize {
        y.min(self.height - 1)
    }

    /// The level's texel index of place `i` (row-major, 0..16) of block
    /// (`bx`, `by`), the edge repeated past it.
    #[inline]
    pub(crate) fn texel(&self, bx: usize, by: usize, i: usize) -> usize {
        self.clamp_y(by * 4 + i / 4) * self.width + self.clamp_x(bx * 4 + i % 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_repeat() {
        let grid = BlockGrid::new(3, 1);
        assert_eq!((grid.across, grid.down), (1, 1));
        let places: Vec<usize> = (0..16).map(|i| grid.texel(0, 0, i)).collect();
        assert_eq!(places, [0, 1, 2, 2, 0, 1, 2, 2, 0, 1, 2, 2, 0, 1, 2, 2]);
        let grid = BlockGrid::new(6, 5);
        assert_eq!((grid.across, grid.down), (2, 2));
        assert_eq!(grid.texel(1, 1, 15), 4 * 6 + 5);
        assert_eq!(grid.texel(1, 1, 0), 4 * 6 + 4);
    }
}
