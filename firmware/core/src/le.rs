//! Little-endian readers and a writer over byte slices that never panic.
//!
//! Readers return 0 for bytes out of bounds (callers check lengths first); the writer skips what
//! does not fit (callers size the buffer first).

// Not inlined: image and trace parsing (load time only) read fields at dozens of places, each
// inlined copy of the range check costs code flash (about 2 KiB in the QEMU group firmware).
#[inline(never)]
pub(crate) fn rd<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    match b.get(off..off.wrapping_add(N)) {
        Some(s) => <[u8; N]>::try_from(s).unwrap_or([0; N]),
        None => [0; N],
    }
}
pub(crate) fn u8_at(b: &[u8], off: usize) -> u8 {
    b.get(off).copied().unwrap_or(0)
}
pub(crate) fn u16_at(b: &[u8], off: usize) -> u16 {
    u16::from_le_bytes(rd(b, off))
}
pub(crate) fn u32_at(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(rd(b, off))
}
pub(crate) fn i32_at(b: &[u8], off: usize) -> i32 {
    i32::from_le_bytes(rd(b, off))
}
pub(crate) fn i64_at(b: &[u8], off: usize) -> i64 {
    i64::from_le_bytes(rd(b, off))
}
pub(crate) fn f32_at(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes(rd(b, off))
}

/// Sequential little-endian writer.
pub(crate) struct Put<'a> {
    pub(crate) buf: &'a mut [u8],
    pub(crate) pos: usize,
}

impl<'a> Put<'a> {
    pub(crate) fn new(buf: &'a mut [u8]) -> Put<'a> {
        Put { buf, pos: 0 }
    }
    pub(crate) fn bytes(&mut self, v: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.pos..self.pos.wrapping_add(v.len())) {
            dst.copy_from_slice(v);
        }
        self.pos = self.pos.wrapping_add(v.len());
    }
    pub(crate) fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }
    pub(crate) fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    pub(crate) fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(crate) fn i32(&mut self, v: i32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(crate) fn i64(&mut self, v: i64) {
        self.bytes(&v.to_le_bytes());
    }
    pub(crate) fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
}
