//! Byte framing of saved states: the physics writes and reads its part with [`ByteReader`];
//! whoever embeds it frames what it saves with [`frame`] and [`unframe`] (a magic naming the
//! format and its version, the length, and an FNV-1a 64 checksum).

fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100000001b3))
}

/// magic | body length (u64) | body | FNV-1a 64 of body. The magic names the format
/// and its version (each layer of a saved state has its own).
pub fn frame(magic: &[u8; 8], body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + 24);
    out.extend_from_slice(magic);
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    out.extend_from_slice(&checksum(body).to_le_bytes());
    out
}

pub fn unframe<'a>(magic: &[u8; 8], bytes: &'a [u8]) -> Result<&'a [u8], String> {
    if bytes.len() < 24 || &bytes[..8] != magic {
        return Err("not an EhsvActuator state (wrong magic or version)".into());
    }
    let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap());
    if len != (bytes.len() - 24) as u64 {
        return Err(format!("state length {} does not match its header ({len})", bytes.len() - 24));
    }
    let body = &bytes[16..bytes.len() - 8];
    let sum = u64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap());
    if sum != checksum(body) {
        return Err("state checksum mismatch (corrupted bytes)".into());
    }
    Ok(body)
}

/// Bounds-checked little-endian reader for state bytes.
pub struct ByteReader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> ByteReader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        ByteReader { bytes, at: 0 }
    }

    /// Whether every byte was read (a longer input is not this format).
    pub fn is_at_end(&self) -> bool {
        self.at == self.bytes.len()
    }
}

impl ByteReader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or("state is truncated")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    pub fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
}
