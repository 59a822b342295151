//! A stable fingerprint of bytes: what a checkpoint's checksums and a cache's keys are made of,
//! the same on every machine and in every version (std's hashers promise neither).

/// FNV-1a, 64 bits: what a flipped bit anywhere in what it is fed changes.
#[derive(Clone, Debug)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// A fingerprint of nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `bytes`.
    pub fn feed(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 = (self.0 ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Adds `bytes` after their length, so that where one part ends and the next begins counts.
    pub fn feed_part(&mut self, bytes: &[u8]) {
        self.feed(&(bytes.len() as u64).to_le_bytes());
        self.feed(bytes);
    }

    /// The fingerprint as 16 hexadecimal digits.
    pub fn finish(&self) -> String {
        format!("{:016x}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::Fnv;

    /// FNV-1a's published value for "a", and parts that differ only in where they split differ.
    #[test]
    fn known_values_and_parts() {
        let mut a = Fnv::new();
        a.feed(b"a");
        assert_eq!(a.finish(), "af63dc4c8601ec8c");
        let (mut ab_c, mut a_bc) = (Fnv::new(), Fnv::new());
        ab_c.feed_part(b"ab");
        ab_c.feed_part(b"c");
        a_bc.feed_part(b"a");
        a_bc.feed_part(b"bc");
        assert_ne!(ab_c.finish(), a_bc.finish());
    }
}
