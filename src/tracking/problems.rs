//! Counting bad input: every kind of problem is counted, and logged once (the first time it
//! happens), so a flood of garbage cannot flood the log.

use std::collections::BTreeMap;
use std::fmt::Display;

/// Problem counters keyed by a stable kind name (e.g. `dtrack_bad_token`, `replay_not_json`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ProblemLog {
    counts: BTreeMap<&'static str, u64>,
    /// The one message logged per kind: the first problem's detail.
    first: BTreeMap<&'static str, String>,
    /// When set, nothing is printed (tests, benchmarks); counting is unaffected.
    pub quiet: bool,
}

impl ProblemLog {
    #[must_use]
    pub fn quiet() -> Self {
        Self {
            quiet: true,
            ..Self::default()
        }
    }

    /// Counts one problem of `kind`; prints `detail` to stderr if it is the first of its kind.
    pub fn report(&mut self, kind: &'static str, detail: impl Display) {
        let n = self.counts.entry(kind).or_insert(0);
        *n += 1;
        if *n == 1 {
            let message = detail.to_string();
            if !self.quiet {
                eprintln!(
                    "raygun: {kind}: {message} (further problems of this kind are only counted)"
                );
            }
            self.first.insert(kind, message);
        }
    }

    /// How many problems of `kind` were reported.
    #[must_use]
    pub fn count(&self, kind: &str) -> u64 {
        self.counts.get(kind).copied().unwrap_or(0)
    }

    /// The message logged for `kind` (its first problem), if any was reported.
    #[must_use]
    pub fn logged(&self, kind: &str) -> Option<&str> {
        self.first.get(kind).map(String::as_str)
    }

    /// All problems reported.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.counts.values().sum()
    }

    /// Counts per kind, sorted by name.
    #[must_use]
    pub fn counts(&self) -> &BTreeMap<&'static str, u64> {
        &self.counts
    }

    /// Adds another log's counts to this one.
    pub fn merge(&mut self, other: &ProblemLog) {
        for (k, v) in &other.counts {
            *self.counts.entry(k).or_insert(0) += v;
        }
        for (k, m) in &other.first {
            self.first.entry(k).or_insert_with(|| m.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_per_kind_and_in_total() {
        let mut log = ProblemLog::quiet();
        log.report("a", "x");
        log.report("a", "y");
        log.report("b", "z");
        assert_eq!((log.count("a"), log.count("b"), log.count("c")), (2, 1, 0));
        // Logged once per kind: the first detail is kept, later ones are only counted.
        assert_eq!((log.logged("a"), log.logged("c")), (Some("x"), None));
        assert_eq!(log.total(), 3);
        let mut other = ProblemLog::quiet();
        other.merge(&log);
        other.merge(&log);
        assert_eq!(other.count("a"), 4);
    }
}
