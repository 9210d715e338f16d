//! Values quoted in messages, kept short: a message that echoes a 10 MB field or prints 1e308 as
//! 309 digits buries what it is about.

/// Longest quoted text, in characters.
pub const MAX_QUOTED_CHARS: usize = 60;

/// `text` as a quoted, escaped string (`"…"` with control characters escaped), cut to
/// [`MAX_QUOTED_CHARS`] characters with the full length said when longer.
#[must_use]
pub fn quote(text: &str) -> String {
    let n = text.chars().count();
    if n <= MAX_QUOTED_CHARS {
        return format!("{text:?}");
    }
    let head: String = text.chars().take(MAX_QUOTED_CHARS).collect();
    format!("{head:?}… ({n} characters)")
}

/// Bytes for people: "1.5 GB", "640 MB", "12 kB", "10 bytes".
#[must_use]
pub fn bytes(b: u64) -> String {
    if b < 1000 {
        return format!("{b} bytes");
    }
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.0} kB", b / 1e3)
    }
}

/// `n` and `noun` in the number `n` takes: "1 triangle", "2 triangles", "3 presses", "0 eyes".
/// The noun is a singular English noun (or noun phrase) whose plural adds `s`, or `es` after
/// s, x, z, ch and sh.
#[must_use]
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        return format!("1 {noun}");
    }
    let es = ["s", "x", "z", "ch", "sh"]
        .iter()
        .any(|e| noun.ends_with(e));
    format!("{n} {noun}{}", if es { "es" } else { "s" })
}

/// serde_json's message for `e`, an error in parsing `text`, without its " at line L column C"
/// (callers say where in their own form), clipped, and with a word on the mistakes its message
/// does not explain: `NaN` and `Infinity`, which JSON has no numbers for.
#[must_use]
pub fn json_message(e: &serde_json::Error, text: &str) -> String {
    let full = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    let message = clip(full.strip_suffix(&suffix).unwrap_or(&full));
    // serde_json's column is the byte after the one it stopped at, 1-based.
    let at = text
        .lines()
        .nth(e.line().saturating_sub(1))
        .and_then(|l| l.get(e.column().saturating_sub(1)..).or(Some(l)))
        .unwrap_or("");
    let at = at.trim_start_matches(['-', '+']);
    let words = ["NaN", "nan", "Infinity", "infinity", "inf", "Inf"];
    if words.iter().any(|w| at.starts_with(w)) {
        return format!("{message}: NaN and Infinity are not JSON numbers (give a finite number)");
    }
    message
}

/// A message from elsewhere (a parser's) cut to a few hundred characters: serde quotes the
/// offending value whole, however long it is.
#[must_use]
pub fn clip(message: &str) -> String {
    const MAX: usize = 300;
    let n = message.chars().count();
    if n <= MAX {
        return message.to_owned();
    }
    let head: String = message.chars().take(MAX).collect();
    format!("{head}… ({n} characters)")
}

/// A library's message without the source locations some put in it ("os error at
/// /root/.cargo/registry/…/mod.rs:788: Failed to open…" becomes "os error: Failed to open…"):
/// they name files the user does not have.
#[must_use]
pub fn without_source_paths(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(i) = rest.find(" at /") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 4..];
        // The path runs to ".rs:LINE" (and an optional ":COLUMN").
        match after.find(".rs:") {
            Some(j) => {
                let tail = &after[j + 4..];
                let digits = tail
                    .find(|c: char| !(c.is_ascii_digit() || c == ':'))
                    .unwrap_or(tail.len());
                rest = tail[digits..].trim_start_matches(':');
                if !rest.starts_with(' ') && !rest.is_empty() {
                    out.push(' ');
                } else if rest.starts_with(' ') {
                    out.push(':');
                }
            }
            None => {
                out.push_str(&rest[i..]);
                rest = "";
            }
        }
    }
    out.push_str(rest);
    out
}

/// A number for a message: as Rust prints it where that is short, else with 6 significant
/// digits, in exponent form outside [1e-4, 1e15) (`1e308`, not 309 digits).
#[must_use]
pub fn number(v: f64) -> String {
    let plain = format!("{v}");
    let a = v.abs();
    if !v.is_finite() || (plain.len() <= 16 && (a >= 1e-4 || a == 0.0)) {
        return plain;
    }
    if (1e-4..1e15).contains(&a) {
        let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        return if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        };
    }
    let e = format!("{v:.5e}");
    // Trim the mantissa's trailing zeros: 1.00000e308 → 1e308.
    match e.split_once('e') {
        Some((m, x)) if m.contains('.') => {
            let m = m.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{x}")
        }
        _ => e,
    }
}

/// An error and its sources as one line, `outer: inner: …`, each message once (a wrapper
/// that repeats its source's text adds nothing).
#[must_use]
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    join_causes(std::iter::successors(Some(e), |e| e.source()).map(ToString::to_string))
}

/// Causes joined with `: `, skipping empty ones and ones already said.
#[must_use]
pub fn join_causes(causes: impl IntoIterator<Item = String>) -> String {
    let mut out = String::new();
    for text in causes {
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_text_is_cut_and_its_length_said() {
        let long = "x".repeat(10_000_000);
        let q = quote(&long);
        assert!(q.len() < 100, "{q}");
        assert!(q.contains("10000000 characters"), "{q}");
        assert_eq!(quote("c3r2"), "\"c3r2\"");
        assert_eq!(quote("a\nb"), "\"a\\nb\"");
    }

    #[test]
    fn source_paths_are_dropped() {
        assert_eq!(
            without_source_paths(
                "winit EventLoopError: os error at /root/.cargo/registry/src/x/winit-0.30.13/src/platform_impl/linux/mod.rs:788: Failed to open connection to X server"
            ),
            "winit EventLoopError: os error: Failed to open connection to X server"
        );
        assert_eq!(
            without_source_paths("look at /tmp/x.png"),
            "look at /tmp/x.png"
        );
        assert_eq!(without_source_paths("plain"), "plain");
    }

    #[test]
    fn numbers_stay_short() {
        assert_eq!(number(1e308), "1e308");
        assert_eq!(number(-1.5e-9), "-1.5e-9");
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(3840.0), "3840");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(number(1.0 / 3.0), "0.333333");
        assert_eq!(number(12_345.678_901_234_567), "12345.7");
        assert!(number(f64::MAX).len() < 16);
    }

    #[test]
    fn counts_take_their_number() {
        assert_eq!(count(1, "triangle"), "1 triangle");
        assert_eq!(count(0, "triangle"), "0 triangles");
        assert_eq!(count(2, "press"), "2 presses");
        assert_eq!(count(1, "press"), "1 press");
        assert_eq!(count(35, "tile image"), "35 tile images");
    }

    #[test]
    fn json_messages_say_that_nan_is_no_json_number() {
        for (text, bad) in [
            ("{\"a\": NaN}", true),
            ("[1,\n -Infinity]", true),
            ("{\"a\": 1,}", false),
            ("{\"a\": nope}", false),
        ] {
            let e = serde_json::from_str::<serde_json::Value>(text).unwrap_err();
            let m = json_message(&e, text);
            assert_eq!(
                m.contains("NaN and Infinity are not JSON numbers"),
                bad,
                "{text}: {m}"
            );
            assert!(!m.contains(" at line "), "{m}");
        }
    }
}
