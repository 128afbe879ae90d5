//! A buffered reader whose seeks keep the buffer when they land in it.

use std::io::{self, BufReader, Read, Seek, SeekFrom};

/// [`BufReader`] for decoders that seek to every chunk they read, as the
/// `tiff` crate does (`Seek::seek(SeekFrom::Start(offset))` before each
/// strip or tile): `BufReader::seek` empties the buffer every time, so a
/// GeoTIFF of one-row strips (GDAL's default, 16 KiB each at 4096 float32
/// texels) was read into a 64 KiB buffer four times over. Here a seek that
/// lands inside the buffer moves within it ([`BufReader::seek_relative`]),
/// so consecutive chunks are copied from the kernel once. Positions are
/// tracked here, since `seek_relative` does not return one.
pub(crate) struct SeekableBufReader<R> {
    inner: BufReader<R>,
    /// The position of the next byte [`Read::read`] gives.
    position: u64,
}

impl<R: Read + Seek> SeekableBufReader<R> {
    /// Buffers `inner` with `capacity` bytes, from its present position.
    pub(crate) fn with_capacity(capacity: usize, mut inner: R) -> io::Result<Self> {
        let position = inner.stream_position()?;
        Ok(SeekableBufReader { inner: BufReader::with_capacity(capacity, inner), position })
    }
}

impl<R: Read> Read for SeekableBufReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.position += n as u64;
        Ok(n)
    }
}

impl<R: Read + Seek> Seek for SeekableBufReader<R> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let delta = match to {
            SeekFrom::Start(target) => i64::try_from(i128::from(target) - i128::from(self.position)).ok(),
            SeekFrom::Current(delta) => Some(delta),
            SeekFrom::End(_) => None,
        };
        let target = delta.and_then(|d| self.position.checked_add_signed(d));
        match (delta, target) {
            (Some(delta), Some(target)) => match self.inner.seek_relative(delta) {
                Ok(()) => self.position = target,
                Err(e) => {
                    // Where the failed seek left the reader.
                    self.position = self.inner.stream_position()?;
                    return Err(e);
                }
            },
            // From the end, or a position no u64 holds (which the inner
            // reader refuses): the plain seek, which empties the buffer.
            _ => self.position = self.inner.seek(to)?,
        }
        Ok(self.position)
    }

    fn stream_position(&mut self) -> io::Result<u64> {
        Ok(self.position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// Every sequence of seeks and reads gives the bytes the plain reader
    /// gives, in and out of the buffer, forwards and back.
    #[test]
    fn seeks_and_reads_as_the_plain_reader_does() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let mut ours = SeekableBufReader::with_capacity(64, Cursor::new(data.clone())).unwrap();
        let mut plain = Cursor::new(data);
        let steps = [
            (SeekFrom::Start(10), 5),
            (SeekFrom::Start(15), 20),
            (SeekFrom::Current(-30), 7),
            (SeekFrom::Start(500), 100),
            (SeekFrom::Current(3), 1),
            (SeekFrom::End(-4), 4),
            (SeekFrom::Start(0), 64),
            (SeekFrom::Start(63), 2),
            (SeekFrom::Start(998), 10),
        ];
        for (to, len) in steps {
            assert_eq!(ours.seek(to).unwrap(), plain.seek(to).unwrap(), "{to:?}");
            let (mut a, mut b) = (Vec::new(), Vec::new());
            (&mut ours).take(len).read_to_end(&mut a).unwrap();
            (&mut plain).take(len).read_to_end(&mut b).unwrap();
            assert_eq!(a, b, "{to:?}");
            assert_eq!(ours.stream_position().unwrap(), plain.stream_position().unwrap());
        }
        assert!(ours.seek(SeekFrom::Current(-5000)).is_err());
        let at = plain.stream_position().unwrap();
        assert_eq!(ours.stream_position().unwrap(), at, "a failed seek leaves the position");
    }
}
