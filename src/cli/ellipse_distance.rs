//! `raygun ellipse-distance`: the closest point on an ellipse for each line of a CSV stream.
//!
//! Input, one query per line: `a,b,x,y` (semi-axes along x and y, then the point; any quadrant).
//! Whitespace around fields is ignored; blank lines and lines starting with `#` (after leading
//! whitespace) are skipped and produce no output.
//!
//! Output, one line per query line: `distance,cx,cy` — the distance to the ellipse *curve* and the
//! closest point on it, each printed so that it parses back to the same f64 (Rust's shortest
//! round-trip form; exponent form outside `[1e-5, 1e16)` so that no number prints hundreds of
//! digits).
//!
//! A bad query line (wrong field count, a field that is not a number, NaN or infinity, a negative
//! semi-axis, bytes that are not UTF-8, a line longer than [`MAX_LINE`]) writes `error: line N: <what>` to the error stream and
//! `nan,nan,nan` to the output. The placeholder keeps the k-th output line paired with the k-th
//! query line, so a user who pastes the output next to the input, or feeds both to a CSV reader,
//! never shifts rows after a typo; any CSV reader reads `nan` as a missing value. The remaining
//! lines still run. [`LineStats::errors`] lets the binary exit non-zero after the whole stream.

use std::io::{self, BufRead, Write};

use glam::DVec2;

use crate::roi::ellipse::closest_point_on_ellipse;

/// What [`run`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineStats {
    /// Query lines answered (good and bad; blank and comment lines are not counted).
    pub queries: usize,
    /// Query lines that were rejected (each got an `error:` line and `nan,nan,nan`).
    pub errors: usize,
}

/// Why a query line was rejected; the message names the field at fault.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum LineError {
    #[error("expected 4 comma-separated fields a,b,x,y, found {0}")]
    FieldCount(usize),
    #[error("field {field} ({name}) is not a number: {text:?}")]
    NotANumber {
        field: usize,
        name: &'static str,
        text: String,
    },
    #[error("field {field} ({name}) is not finite: {text:?}")]
    NotFinite {
        field: usize,
        name: &'static str,
        text: String,
    },
    #[error("field {field} ({name}) is a negative semi-axis: {value}")]
    NegativeSemiAxis {
        field: usize,
        name: &'static str,
        value: f64,
    },
    #[error("line is not valid UTF-8")]
    NotUtf8,
    #[error("line is longer than {MAX_LINE} bytes")]
    TooLong,
}

/// Longest query line read (four numbers take at most a few hundred bytes); the rest of a
/// longer line is skipped and the line answered as an error.
pub const MAX_LINE: usize = 4096;

const FIELD_NAMES: [&str; 4] = ["a", "b", "x", "y"];

/// Parses one query line (already known not to be blank or a comment) into `[a, b, x, y]`.
pub fn parse_query(line: &str) -> Result<[f64; 4], LineError> {
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    if fields.len() != 4 {
        return Err(LineError::FieldCount(fields.len()));
    }
    let mut values = [0.0; 4];
    for (i, (text, name)) in fields.iter().zip(FIELD_NAMES).enumerate() {
        let field = i + 1;
        let value: f64 = text.parse().map_err(|_| LineError::NotANumber {
            field,
            name,
            text: (*text).to_owned(),
        })?;
        // Rust parses "nan" and "inf"; they are no valid geometry.
        if !value.is_finite() {
            return Err(LineError::NotFinite {
                field,
                name,
                text: (*text).to_owned(),
            });
        }
        if i < 2 && value < 0.0 {
            return Err(LineError::NegativeSemiAxis { field, name, value });
        }
        values[i] = value;
    }
    Ok(values)
}

/// Formats an f64 so that it parses back to itself, without hundreds of digits.
#[must_use]
pub fn format_f64(v: f64) -> String {
    let m = v.abs();
    if m == 0.0 || (1e-5..1e16).contains(&m) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Runs the command over `input`; see the module docs for the formats. Only I/O errors on the
/// streams abort; bad lines are reported and counted.
pub fn run(
    mut input: impl BufRead,
    mut out: impl Write,
    mut err: impl Write,
) -> io::Result<LineStats> {
    let mut stats = LineStats::default();
    let mut buf = Vec::new();
    let mut line_no = 0usize;
    loop {
        let line = crate::input::read_line(&mut input, &mut buf, MAX_LINE)?;
        if line == crate::input::Line::End {
            break;
        }
        line_no += 1;
        let parsed = match std::str::from_utf8(&buf) {
            _ if line == crate::input::Line::TooLong => Err(LineError::TooLong),
            Ok(text) => {
                let text = text.trim();
                if text.is_empty() || text.starts_with('#') {
                    continue;
                }
                parse_query(text)
            }
            Err(_) => Err(LineError::NotUtf8),
        };
        stats.queries += 1;
        match parsed {
            Ok([a, b, x, y]) => {
                let c = closest_point_on_ellipse(a, b, DVec2::new(x, y));
                writeln!(
                    out,
                    "{},{},{}",
                    format_f64(c.distance),
                    format_f64(c.point.x),
                    format_f64(c.point.y)
                )?;
            }
            Err(e) => {
                stats.errors += 1;
                writeln!(err, "error: line {line_no}: {e}")?;
                writeln!(out, "nan,nan,nan")?;
            }
        }
    }
    out.flush()?;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_str(input: &str) -> (String, String, LineStats) {
        let mut out = Vec::new();
        let mut err = Vec::new();
        let stats = run(input.as_bytes(), &mut out, &mut err).unwrap();
        (
            String::from_utf8(out).unwrap(),
            String::from_utf8(err).unwrap(),
            stats,
        )
    }

    #[test]
    fn circle_point_outside_gives_exact_distance_and_point() {
        // Circle of radius 1, point (3, 4): distance 5 − 1 = 4, closest point (0.6, 0.8).
        let (out, err, stats) = run_str("1,1,3,4\n");
        let fields: Vec<f64> = out.trim().split(',').map(|f| f.parse().unwrap()).collect();
        assert!((fields[0] - 4.0).abs() < 1e-15, "{out}");
        assert!((fields[1] - 0.6).abs() < 1e-15 && (fields[2] - 0.8).abs() < 1e-15);
        assert_eq!(err, "");
        assert_eq!(
            stats,
            LineStats {
                queries: 1,
                errors: 0
            }
        );
    }

    #[test]
    fn whitespace_blank_lines_comments_and_crlf_are_tolerated() {
        let (out, err, stats) = run_str("# header\n\n  2 , 1 ,\t0 , 5 \r\n   # indented comment\n");
        assert_eq!(out, "4,0,1\n");
        assert_eq!(err, "");
        assert_eq!(stats.queries, 1);
    }

    #[test]
    fn bad_lines_report_their_number_and_keep_output_aligned() {
        let input = "2,1,0,5\n1,2,3\nx,1,0,0\n1,1,nan,0\n-1,1,0,0\n1,1,inf,0\n2,1,5,0\n";
        let (out, err, stats) = run_str(input);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(
            lines,
            [
                "4,0,1",
                "nan,nan,nan",
                "nan,nan,nan",
                "nan,nan,nan",
                "nan,nan,nan",
                "nan,nan,nan",
                "3,2,0"
            ]
        );
        let errs: Vec<&str> = err.lines().collect();
        assert_eq!(errs.len(), 5);
        assert!(
            errs[0].starts_with("error: line 2: expected 4"),
            "{}",
            errs[0]
        );
        assert!(errs[1].starts_with("error: line 3: field 1 (a) is not a number"));
        assert!(errs[2].starts_with("error: line 4: field 3 (x) is not finite"));
        assert!(errs[3].starts_with("error: line 5: field 1 (a) is a negative semi-axis"));
        assert!(errs[4].starts_with("error: line 6: field 3 (x) is not finite"));
        assert_eq!(
            stats,
            LineStats {
                queries: 7,
                errors: 5
            }
        );
    }

    #[test]
    fn invalid_utf8_is_a_bad_line_not_an_abort() {
        let mut out = Vec::new();
        let mut err = Vec::new();
        let input: &[u8] = b"1,1,\xff,0\n1,1,2,0\n";
        let stats = run(input, &mut out, &mut err).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), "nan,nan,nan\n1,1,0\n");
        assert!(
            String::from_utf8(err)
                .unwrap()
                .contains("line 1: line is not valid UTF-8")
        );
        assert_eq!(stats.errors, 1);
    }

    #[test]
    fn last_line_without_newline_is_answered() {
        let (out, _, _) = run_str("1,1,0,2");
        assert_eq!(out, "1,0,1\n");
    }

    #[test]
    fn printed_numbers_round_trip_including_extremes() {
        for v in [
            0.1,
            1.0 / 3.0,
            1e300,
            -2.5e-310,
            1e16,
            1e16 - 2.0,
            1e-5,
            0.0,
        ] {
            let s = format_f64(v);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
            assert!(s.len() <= 24, "{s}");
        }
    }

    #[test]
    fn huge_inputs_print_in_exponent_form() {
        let (out, err, _) = run_str("1e300,1e300,0,3e300\n");
        assert_eq!(err, "");
        assert_eq!(out, "2e300,0,1e300\n");
    }

    #[test]
    fn an_overlong_line_is_one_error_and_the_stream_goes_on() {
        let long = "1".repeat(MAX_LINE * 3);
        let input = format!("1,1,3,0\n{long}\n1,1,0,2\n");
        let (out, err, stats) = run_str(&input);
        assert_eq!(out, "2,1,0\nnan,nan,nan\n1,0,1\n");
        assert_eq!(
            err,
            format!("error: line 2: line is longer than {MAX_LINE} bytes\n")
        );
        assert_eq!(
            stats,
            LineStats {
                queries: 3,
                errors: 1
            }
        );
    }
}
