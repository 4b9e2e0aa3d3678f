//! A seeded, deterministic byte mutator.

use vps_mesh::builtin::rng::SplitMix64;

/// The deterministic generator of the mutator: `vps_mesh`'s SplitMix64 (not cryptographic).
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// A uniform integer in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// True with probability `1 / n`.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }
}

/// Integers that tend to break size and index arithmetic, as u64 bit patterns.
const INTERESTING_INTS: &[u64] = &[
    0,
    1,
    2,
    3,
    7,
    8,
    16,
    31,
    32,
    63,
    64,
    127,
    128,
    255,
    256,
    1023,
    1024,
    4096,
    65535,
    65536,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    1 << 32,
    1 << 40,
    (1 << 40) + 1,
    0x7FFF_FFFF_FFFF_FFFF,
    0x8000_0000_0000_0000,
    u64::MAX,
    u64::MAX - 1,
];

/// Floats that tend to break numeric validation.
const INTERESTING_F64: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::MAX,
    f64::MIN,
    f64::MIN_POSITIVE,
    5e-324,
    1e-300,
    1e300,
    1e-12,
    1e12,
];

/// Text tokens for text formats (OBJ, ASCII STL and PLY, TOML, JSON lines).
const INTERESTING_TEXT: &[&str] = &[
    "0",
    "-1",
    "1e308",
    "-1e308",
    "1e-308",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "2147483647",
    "-2147483648",
    "\n",
    "\r\n",
    " ",
    "\0",
    "/",
    "//",
    "#",
    "[",
    "]",
    "{",
    "}",
    "\"",
    ",",
    "=",
    "f ",
    "v ",
    "facet normal 0 0 0\n",
    "endsolid\n",
    "element vertex 4294967295\n",
    "element face 1000000000\n",
    "property list uint uint vertex_indices\n",
    "end_header\n",
    "\u{feff}",
    "\u{fffd}",
];

/// Produces mutated inputs from a seed corpus.
#[derive(Clone, Debug)]
pub struct Mutator {
    seeds: Vec<Vec<u8>>,
    /// Upper bound on a mutated input's length (bytes).
    max_len: usize,
}

impl Mutator {
    /// A mutator over `seeds` (at least one); outputs are capped at `max_len` bytes.
    pub fn new(seeds: Vec<Vec<u8>>, max_len: usize) -> Self {
        assert!(!seeds.is_empty(), "a mutator needs at least one seed");
        Self { seeds, max_len }
    }

    /// The seeds.
    pub fn seeds(&self) -> &[Vec<u8>] {
        &self.seeds
    }

    /// Input `index` of the campaign seeded with `seed`: a deterministic function of both. Every
    /// 64th input is an unmutated seed (so valid inputs are exercised too); the others stack one to
    /// six mutations on a seed.
    pub fn input(&self, seed: u64, index: u64) -> Vec<u8> {
        let mut rng = Rng::new(seed ^ index.wrapping_mul(0xD134_2543_DE82_EF95));
        let mut data = self.seeds[rng.below(self.seeds.len())].clone();
        if index.is_multiple_of(64) {
            return data;
        }
        let rounds = 1 + rng.below(6);
        for _ in 0..rounds {
            self.mutate_once(&mut rng, &mut data);
        }
        data.truncate(self.max_len);
        data
    }

    fn mutate_once(&self, rng: &mut Rng, data: &mut Vec<u8>) {
        let len = data.len();
        match rng.below(12) {
            // Flip one bit.
            0 if len > 0 => {
                let i = rng.below(len);
                data[i] ^= 1 << rng.below(8);
            }
            // Overwrite a byte.
            1 if len > 0 => {
                let i = rng.below(len);
                data[i] = rng.next_u64() as u8;
            }
            // Insert random bytes.
            2 => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
                data.splice(at..at, bytes);
            }
            // Delete a range.
            3 if len > 0 => {
                let at = rng.below(len);
                let n = 1 + rng.below((len - at).min(64));
                data.drain(at..at + n);
            }
            // Duplicate a range in place.
            4 if len > 0 => {
                let at = rng.below(len);
                let n = 1 + rng.below((len - at).min(256));
                let copy = data[at..at + n].to_vec();
                let to = rng.below(len + 1);
                data.splice(to..to, copy);
            }
            // Splice: this input's head with another seed's tail.
            5 => {
                let other = &self.seeds[rng.below(self.seeds.len())];
                let cut = rng.below(len + 1);
                let from = rng.below(other.len() + 1);
                data.truncate(cut);
                data.extend_from_slice(&other[from..]);
            }
            // An interesting integer, little-endian, of 1, 2, 4 or 8 bytes.
            6 | 7 if len > 0 => {
                let v = INTERESTING_INTS[rng.below(INTERESTING_INTS.len())];
                let v = if rng.one_in(4) { v.wrapping_neg() } else { v };
                let width = [1, 2, 4, 8][rng.below(4)];
                overwrite(rng, data, &v.to_le_bytes()[..width]);
            }
            // An interesting float, as f64 or f32.
            8 if len > 0 => {
                let v = INTERESTING_F64[rng.below(INTERESTING_F64.len())];
                if rng.one_in(2) {
                    overwrite(rng, data, &v.to_le_bytes());
                } else {
                    overwrite(rng, data, &(v as f32).to_le_bytes());
                }
            }
            // A text token, inserted or replacing a run of digits or letters.
            9 | 10 => {
                let token = INTERESTING_TEXT[rng.below(INTERESTING_TEXT.len())].as_bytes();
                let at = rng.below(len + 1);
                let run = data[at..]
                    .iter()
                    .take_while(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'-' | b'+'))
                    .count();
                let replace = if rng.one_in(2) { run } else { 0 };
                data.splice(at..at + replace, token.iter().copied());
            }
            // Truncate.
            _ => {
                if len > 0 {
                    data.truncate(rng.below(len));
                }
            }
        }
    }
}

/// Overwrites `bytes.len()` bytes at a random offset (clipped at the end).
fn overwrite(rng: &mut Rng, data: &mut [u8], bytes: &[u8]) {
    let at = rng.below(data.len());
    let n = bytes.len().min(data.len() - at);
    data[at..at + n].copy_from_slice(&bytes[..n]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_are_deterministic_and_varied() {
        let m = Mutator::new(
            vec![b"hello world, a seed".to_vec(), vec![0u8; 40]],
            1 << 16,
        );
        let a: Vec<Vec<u8>> = (0..200).map(|i| m.input(7, i)).collect();
        let b: Vec<Vec<u8>> = (0..200).map(|i| m.input(7, i)).collect();
        assert_eq!(a, b);
        let distinct: std::collections::HashSet<&Vec<u8>> = a.iter().collect();
        assert!(
            distinct.len() > 150,
            "only {} distinct inputs",
            distinct.len()
        );
        assert!(m.seeds().contains(&m.input(7, 0)));
        assert!(m.seeds().contains(&m.input(7, 64)));
        assert_ne!(m.input(7, 1), m.input(8, 1));
    }

    #[test]
    fn inputs_respect_the_length_cap() {
        let m = Mutator::new(vec![vec![b'x'; 100]], 120);
        assert!((0..2000).all(|i| m.input(1, i).len() <= 120));
    }
}
