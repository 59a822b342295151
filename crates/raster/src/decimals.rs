//! How SVG numbers are written: a fixed number of decimals, as whole ticks, in the shortest
//! form path data allows. Shared by the shapes' path data and the document's attributes.

use std::fmt::Write as _;

/// The most decimals [`SvgOptions::decimals`] takes: f32 coordinates hold about 7 digits.
pub const MAX_DECIMALS: usize = 6;

/// How SVG numbers are written: rounded to a number of decimals (half to even, as `format!`
/// rounds), as whole *ticks* of 10^−decimals, so that points rounded once can be differenced
/// exactly (relative path data adds up to the rounded points) and written without going
/// through text and back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decimals {
    decimals: usize,
    scale: f64,
}

impl Decimals {
    /// Numbers with `decimals` decimals.
    ///
    /// # Panics
    /// If `decimals` exceeds [`MAX_DECIMALS`].
    pub fn new(decimals: usize) -> Self {
        assert!(decimals <= MAX_DECIMALS, "at most {MAX_DECIMALS} decimals");
        Self { decimals, scale: 10f64.powi(decimals as i32) }
    }

    /// `value` in ticks. An f32 times 10^6 is exact in an f64 (24 + 20 bits), so this is the
    /// decimal rounding of the value itself.
    pub fn ticks(self, value: f32) -> i64 {
        (value as f64 * self.scale).round_ties_even() as i64
    }

    /// `value` rounded as it is written: whole ticks, as a number again.
    pub fn rounded(self, value: f32) -> f32 {
        (self.ticks(value) as f64 / self.scale) as f32
    }

    /// Writes `ticks` as a number with no trailing zeros (`12`, `3.5`, `-0.25`); `short` leaves
    /// out the zero before the point (`.5`, `-.25`), as path data allows.
    pub fn write(self, out: &mut String, ticks: i64, short: bool) {
        if ticks < 0 {
            out.push('-');
        }
        let magnitude = ticks.unsigned_abs();
        let unit = self.scale as u64;
        let (whole, fraction) = (magnitude / unit, magnitude % unit);
        if whole != 0 || fraction == 0 || !short {
            let _ = write!(out, "{whole}");
        }
        if fraction != 0 {
            let (mut fraction, mut width) = (fraction, self.decimals);
            while fraction % 10 == 0 {
                (fraction, width) = (fraction / 10, width - 1);
            }
            let _ = write!(out, ".{fraction:0width$}");
        }
    }

    /// `value` as [`Decimals::write`] writes it in full (`0.5`, not `.5`).
    pub fn number(self, value: f32) -> String {
        let mut out = String::new();
        self.write(&mut out, self.ticks(value), false);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short() {
        let number = |value: f32, decimals: usize| Decimals::new(decimals).number(value);
        assert_eq!(number(12.0, 2), "12");
        assert_eq!(number(3.5, 2), "3.5");
        assert_eq!(number(-0.001, 2), "0");
        assert_eq!(number(0.126, 2), "0.13");
        assert_eq!(number(120.0, 0), "120");
        assert_eq!(number(12.34567, 4), "12.3457");
        assert_eq!(number(-0.25, 2), "-0.25");
        let mut short = String::new();
        Decimals::new(2).write(&mut short, -25, true);
        Decimals::new(2).write(&mut short, 50, true);
        Decimals::new(2).write(&mut short, 0, true);
        assert_eq!(short, "-.25.50");
    }

    #[test]
    fn numbers_round_as_format_does() {
        // Ties (k + ½ ticks, exact in binary) go to even, as `format!` rounds; everything else
        // to the nearer tick, whatever its size.
        let mut values: Vec<f32> = vec![0.125, 0.375, -0.125, 2.5, 3.5, -2.5, 0.5, 1.5, 1e-7, -1e-7, 8191.99];
        let mut state = 0x2545_f491_u32;
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            values.push(f32::from_bits(state % 0x4600_0000) * if state % 2 == 0 { 1.0 } else { -1.0 });
        }
        for decimals in 0..=MAX_DECIMALS {
            for &value in &values {
                let text = format!("{value:.decimals$}");
                let text =
                    if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
                let want = if text == "-0" { "0" } else { text };
                assert_eq!(Decimals::new(decimals).number(value), want, "{value} at {decimals} decimals");
            }
        }
    }
}
