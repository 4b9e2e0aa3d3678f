//! The little-endian writer over a fixed-size buffer that the cluster's frame datagrams
//! (`vps-cluster`) and the device bridge's datagrams (`vps-input`) are encoded with. Sizes are the
//! caller's: each message's length is fixed by its format and its buffer is at least that long, so
//! the writer does not check (a write past the end of the buffer panics). Does not allocate.
//!
//! Where this crate sits in vps: `docs/architecture.md#crates` at the repository root.

#![warn(missing_docs)]

/// Sequential writer into `bytes`, starting at a given offset (after a header the caller wrote).
pub struct SliceWriter<'a> {
    bytes: &'a mut [u8],
    at: usize,
}

impl<'a> SliceWriter<'a> {
    /// A writer whose first write lands at `bytes[at]`.
    pub fn new(bytes: &'a mut [u8], at: usize) -> Self {
        SliceWriter { bytes, at }
    }

    /// Copies `b` to the current offset and moves past it. Panics past the end of the buffer.
    pub fn put(&mut self, b: &[u8]) {
        self.bytes[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }

    /// Writes each value as 4 little-endian bytes.
    pub fn f32s(&mut self, v: &[f32]) {
        v.iter().for_each(|x| self.put(&x.to_le_bytes()));
    }

    /// Writes each value as 8 little-endian bytes.
    pub fn f64s(&mut self, v: &[f64]) {
        v.iter().for_each(|x| self.put(&x.to_le_bytes()));
    }

    /// The offset the next write lands at: the bytes written so far plus the starting offset.
    pub fn position(&self) -> usize {
        self.at
    }
}

#[cfg(test)]
mod tests {
    use super::SliceWriter;

    #[test]
    fn writes_follow_each_other_little_endian_after_the_start() {
        let mut buf = [0xAAu8; 20];
        let mut w = SliceWriter::new(&mut buf, 2);
        w.put(&[1, 2]);
        w.f32s(&[1.0]);
        w.f64s(&[-2.0]);
        assert_eq!(w.position(), 16);
        assert_eq!(buf[..4], [0xAA, 0xAA, 1, 2]);
        assert_eq!(buf[4..8], 1.0f32.to_le_bytes());
        assert_eq!(buf[8..16], (-2.0f64).to_le_bytes());
        assert_eq!(buf[16..], [0xAA; 4]);
    }

    #[test]
    #[should_panic]
    fn a_write_past_the_end_panics() {
        let mut buf = [0u8; 4];
        SliceWriter::new(&mut buf, 2).f32s(&[1.0]);
    }
}
