//! A minimal CDR writer and reader for the ROS 2 messages in a recording.
//!
//! ROS 2's default middleware serializes messages as OMG CDR (the "plain CDR" of XCDR
//! version 1, OMG DDS-XTypes 1.3 §7.4.3.5 / OMG CORBA 3.4 Part 2 §9.3), which rosbag2 and the
//! MCAP `cdr` message encoding store verbatim: a 4-byte encapsulation header (`0x00 0x01`,
//! CDR_LE, then two option bytes `0x00 0x00`), then every primitive aligned to its own size
//! counted from the end of that header, strings as a `u32` length that includes the
//! terminating NUL, sequences as a `u32` element count, fixed arrays with no count.

use super::DatasetError;

/// The encapsulation header of little-endian plain CDR.
const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Serializes one message; alignment is relative to the end of the encapsulation header.
#[derive(Debug)]
pub(crate) struct CdrWriter {
    buf: Vec<u8>,
}

impl CdrWriter {
    pub fn with_capacity(capacity: usize) -> Self {
        let mut buf = Vec::with_capacity(capacity + 4);
        buf.extend_from_slice(&CDR_LE);
        Self { buf }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A sequence length (`T[]`); the elements follow.
    pub fn seq_len(&mut self, n: usize) {
        self.u32(n as u32);
    }

    /// `uint8[]`: a count and the raw bytes.
    pub fn bytes(&mut self, data: &[u8]) {
        self.seq_len(data.len());
        self.buf.extend_from_slice(data);
    }

    /// `uint8[]` holding `values` as little-endian `f32`s (an image's `32FC1` data): a byte
    /// count and the values' bits, NaN payloads included.
    pub fn f32_as_bytes(&mut self, values: &[f32]) {
        self.seq_len(4 * values.len());
        self.buf.reserve(4 * values.len());
        for &v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// `float32[]`.
    pub fn f32_seq(&mut self, values: &[f32]) {
        self.seq_len(values.len());
        for &v in values {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Deserializes one message; every read names what was expected when the data ends early.
#[derive(Debug)]
pub(crate) struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    pub fn new(data: &'a [u8]) -> Result<Self, DatasetError> {
        match data.get(..4) {
            Some(header) if header == CDR_LE => Ok(Self { data, pos: 4 }),
            Some(header) => Err(DatasetError::decode(format!(
                "encapsulation header {header:02x?}, expected little-endian CDR {CDR_LE:02x?}"
            ))),
            None => Err(DatasetError::decode("message shorter than its CDR header")),
        }
    }

    fn take(&mut self, align: usize, n: usize) -> Result<&'a [u8], DatasetError> {
        let rel = self.pos - 4;
        let start = self.pos + (align - rel % align) % align;
        let end = start + n;
        let bytes = self.data.get(start..end).ok_or_else(|| {
            DatasetError::decode(format!(
                "message ends at byte {} while reading {n} bytes at {start}",
                self.data.len()
            ))
        })?;
        self.pos = end;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self, align: usize) -> Result<[u8; N], DatasetError> {
        Ok(self.take(align, N)?.try_into().expect("took N bytes"))
    }

    pub fn u8(&mut self) -> Result<u8, DatasetError> {
        Ok(self.take(1, 1)?[0])
    }

    pub fn bool(&mut self) -> Result<bool, DatasetError> {
        Ok(self.u8()? != 0)
    }

    pub fn u16(&mut self) -> Result<u16, DatasetError> {
        Ok(u16::from_le_bytes(self.array(2)?))
    }

    pub fn u32(&mut self) -> Result<u32, DatasetError> {
        Ok(u32::from_le_bytes(self.array(4)?))
    }

    pub fn i32(&mut self) -> Result<i32, DatasetError> {
        Ok(i32::from_le_bytes(self.array(4)?))
    }

    pub fn f32(&mut self) -> Result<f32, DatasetError> {
        Ok(f32::from_le_bytes(self.array(4)?))
    }

    pub fn f64(&mut self) -> Result<f64, DatasetError> {
        Ok(f64::from_le_bytes(self.array(8)?))
    }

    pub fn string(&mut self) -> Result<String, DatasetError> {
        let n = self.u32()? as usize;
        let bytes = self.take(1, n)?;
        let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(text.to_vec()).map_err(|_| DatasetError::decode("string is not UTF-8"))
    }

    pub fn seq_len(&mut self) -> Result<usize, DatasetError> {
        Ok(self.u32()? as usize)
    }

    pub fn bytes(&mut self) -> Result<&'a [u8], DatasetError> {
        let n = self.seq_len()?;
        self.take(1, n)
    }

    pub fn f32_seq(&mut self) -> Result<Vec<f32>, DatasetError> {
        let n = self.seq_len()?;
        let bytes = self.take(4, n * 4)?;
        Ok(bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aligns_from_the_end_of_the_header() {
        let mut w = CdrWriter::with_capacity(0);
        w.u8(7);
        w.f64(1.5);
        w.string("ab");
        w.f32(2.0);
        let bytes = w.finish();
        // header, u8, 7 pad to 8, f64, len 3, "ab\0", pad 1, f32.
        assert_eq!(bytes.len(), 4 + 1 + 7 + 8 + 4 + 3 + 1 + 4, "{bytes:?}");
        assert_eq!(&bytes[..5], &[0, 1, 0, 0, 7]);
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.u8().unwrap(), 7);
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.string().unwrap(), "ab");
        assert_eq!(r.f32().unwrap(), 2.0);
        assert!(r.f32().is_err(), "reading past the end must fail");
    }
}
