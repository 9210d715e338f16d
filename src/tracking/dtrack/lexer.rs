//! The lexer of one record: whitespace-separated numbers and bracketed blocks, every error
//! naming the record and the field.

use super::*;

/// A tokenizer over one record: tokens are `[`, `]` and runs of other non-space characters.
pub(super) struct Cursor<'a> {
    record: &'static str,
    rest: &'a str,
}

impl<'a> Cursor<'a> {
    pub(super) fn new(record: &'static str, rest: &'a str) -> Self {
        Self { record, rest }
    }

    pub(super) fn peek(&mut self) -> Option<&'a str> {
        self.rest = self.rest.trim_start();
        let s = self.rest;
        let first = s.chars().next()?;
        if first == '[' || first == ']' {
            return Some(&s[..1]);
        }
        let end = s
            .find(|ch: char| ch.is_ascii_whitespace() || ch == '[' || ch == ']')
            .unwrap_or(s.len());
        Some(&s[..end])
    }

    pub(super) fn next(&mut self, field: &'static str) -> Result<&'a str, DtrackErrorKind> {
        let tok = self.peek().ok_or(DtrackErrorKind::Missing {
            record: self.record,
            field,
        })?;
        self.rest = &self.rest[tok.len()..];
        Ok(tok)
    }

    pub(super) fn bad(
        &self,
        field: &'static str,
        expected: &'static str,
        found: &str,
    ) -> DtrackErrorKind {
        DtrackErrorKind::BadToken {
            record: self.record,
            field,
            expected,
            // Bounded: the token goes into logs.
            found: found.chars().take(24).collect(),
        }
    }

    pub(super) fn uint(&mut self, field: &'static str, max: u32) -> Result<u32, DtrackErrorKind> {
        let tok = self.next(field)?;
        let v: u64 = tok
            .parse()
            .map_err(|_| self.bad(field, "an unsigned integer", tok))?;
        if v > u64::from(max) {
            return Err(DtrackErrorKind::OutOfRange {
                record: self.record,
                field,
                value: v as f64,
                min: 0.0,
                max: f64::from(max),
            });
        }
        Ok(v as u32)
    }

    pub(super) fn float(&mut self, field: &'static str) -> Result<f64, DtrackErrorKind> {
        let tok = self.next(field)?;
        // Rust also parses "inf"/"nan"; DTrack never writes them, so they are rejected below.
        let v: f64 = tok.parse().map_err(|_| self.bad(field, "a number", tok))?;
        if !v.is_finite() {
            return Err(DtrackErrorKind::NonFinite {
                record: self.record,
                field,
                value: v,
            });
        }
        Ok(v)
    }

    pub(super) fn float_in(
        &mut self,
        field: &'static str,
        min: f64,
        max: f64,
    ) -> Result<f64, DtrackErrorKind> {
        let v = self.float(field)?;
        if !(min..=max).contains(&v) {
            return Err(DtrackErrorKind::OutOfRange {
                record: self.record,
                field,
                value: v,
                min,
                max,
            });
        }
        Ok(v)
    }

    pub(super) fn open(&mut self, field: &'static str) -> Result<(), DtrackErrorKind> {
        let tok = self.next(field)?;
        if tok == "[" {
            Ok(())
        } else {
            Err(self.bad(field, "'['", tok))
        }
    }

    pub(super) fn close(&mut self, field: &'static str) -> Result<(), DtrackErrorKind> {
        let tok = self.next(field)?;
        if tok == "]" {
            Ok(())
        } else {
            Err(self.bad(field, "']'", tok))
        }
    }

    /// Reads numbers up to the closing bracket into `out`, returning how many there were.
    pub(super) fn block(
        &mut self,
        field: &'static str,
        out: &mut [f64],
    ) -> Result<usize, DtrackErrorKind> {
        self.open(field)?;
        let mut n = 0;
        loop {
            if self.peek() == Some("]") {
                self.next(field)?;
                return Ok(n);
            }
            let v = self.float(field)?;
            if n == out.len() {
                return Err(DtrackErrorKind::BlockLength {
                    record: self.record,
                    field,
                    found: n + 1,
                    expected: "no more",
                });
            }
            out[n] = v;
            n += 1;
        }
    }

    pub(super) fn position_block(&mut self) -> Result<DVec3, DtrackErrorKind> {
        let mut v = [0.0; 6];
        let n = self.block("[position]", &mut v)?;
        if n != 3 && n != 6 {
            return Err(DtrackErrorKind::BlockLength {
                record: self.record,
                field: "[position]",
                found: n,
                expected: "3 (or 6 with Euler angles)",
            });
        }
        Ok(DVec3::new(v[0], v[1], v[2]))
    }

    pub(super) fn rotation_block(&mut self) -> Result<[f64; 9], DtrackErrorKind> {
        let mut v = [0.0; 9];
        let n = self.block("[rotation]", &mut v)?;
        if n != 9 {
            return Err(DtrackErrorKind::BlockLength {
                record: self.record,
                field: "[rotation]",
                found: n,
                expected: "9",
            });
        }
        Ok(v)
    }

    pub(super) fn finish(&mut self) -> Result<(), DtrackErrorKind> {
        match self.peek() {
            None => Ok(()),
            Some(tok) => Err(DtrackErrorKind::Trailing {
                record: self.record,
                found: tok.chars().take(24).collect(),
            }),
        }
    }
}
