//! Validation helpers: each check names the full key path, the value it got, what it must be
//! and why, e.g. `navigation.dock_length_m = 1e300: must be within 0 … 0.25 m (…)`.

use std::fmt;

/// One invalid value: its full key path (e.g. `robot.wheel_diameter_m`), the value as
/// written, and why it is rejected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Issue {
    /// Full TOML key path.
    pub key: String,
    /// The rejected value, formatted (`None` when the issue is about the key itself, such
    /// as a simulator section in a robot's file).
    pub value: Option<String>,
    /// Why the value is rejected: the allowed range and its reason, or the arithmetic of a
    /// cross-key check.
    pub reason: String,
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.value {
            Some(value) => write!(f, "{} = {value}: {}", self.key, self.reason),
            None => write!(f, "{}: {}", self.key, self.reason),
        }
    }
}

/// A number as a person would write it: plain for ordinary magnitudes, exponent notation
/// for very large or very small ones (so `1e300` does not print as 301 digits).
pub(crate) fn num(value: f64) -> String {
    let magnitude = value.abs();
    if value == 0.0 || !value.is_finite() || (1e-4..1e7).contains(&magnitude) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

/// True when any of `keys` (full paths) already has an issue: a cross-key check then stays
/// silent, since its arithmetic on a rejected value would only repeat that issue.
pub(crate) fn any_rejected(issues: &[Issue], keys: &[&str]) -> bool {
    issues
        .iter()
        .any(|issue| keys.contains(&issue.key.as_str()))
}

/// Collects the issues of one section.
pub(crate) struct Checker<'a> {
    section: &'a str,
    issues: &'a mut Vec<Issue>,
}

impl<'a> Checker<'a> {
    pub(crate) fn new(section: &'a str, issues: &'a mut Vec<Issue>) -> Self {
        Self { section, issues }
    }

    /// Record an issue for `key` (holding `value`) when `ok` is false.
    pub(crate) fn require(
        &mut self,
        key: &str,
        value: impl fmt::Display,
        ok: bool,
        reason: impl FnOnce() -> String,
    ) {
        if !ok {
            self.issues.push(Issue {
                key: format!("{}.{key}", self.section),
                value: Some(value.to_string()),
                reason: reason(),
            });
        }
    }

    /// Record an issue for `key` when `ok` is false, without a value (the issue is about
    /// several values at once, named in `reason`).
    pub(crate) fn require_all(&mut self, key: &str, ok: bool, reason: impl FnOnce() -> String) {
        if !ok {
            self.issues.push(Issue {
                key: format!("{}.{key}", self.section),
                value: None,
                reason: reason(),
            });
        }
    }

    /// Finite and within `lo … hi` (inclusive) in `unit`; `why` says where the bounds come
    /// from.
    pub(crate) fn within(
        &mut self,
        key: &str,
        value: f64,
        lo: f64,
        hi: f64,
        unit: &str,
        why: &str,
    ) {
        self.require(
            key,
            num(value),
            value.is_finite() && (lo..=hi).contains(&value),
            || range_reason(&num(lo), &num(hi), unit, why),
        );
    }

    /// An integer within `lo … hi` (inclusive) in `unit`; `why` says where the bounds come
    /// from. Takes `i128` so that every integer key fits without a cast.
    pub(crate) fn within_int(
        &mut self,
        key: &str,
        value: impl Into<i128>,
        lo: i128,
        hi: i128,
        unit: &str,
        why: &str,
    ) {
        let value = value.into();
        self.require(key, value, (lo..=hi).contains(&value), || {
            range_reason(&lo.to_string(), &hi.to_string(), unit, why)
        });
    }

    /// Not empty after trimming.
    pub(crate) fn non_empty(&mut self, key: &str, value: &str, why: &str) {
        self.require(key, format!("{value:?}"), !value.trim().is_empty(), || {
            format!("must not be empty ({why})")
        });
    }
}

fn range_reason(lo: &str, hi: &str, unit: &str, why: &str) -> String {
    let unit = match unit {
        "" => String::new(),
        "°" => unit.to_owned(),
        _ => format!(" {unit}"),
    };
    format!("must be within {lo} … {hi}{unit} ({why})")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_short_and_issues_name_key_value_range_and_reason() {
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(0.05), "0.05");
        assert_eq!(num(f64::NAN), "NaN");
        assert_eq!(num(-f64::INFINITY), "-inf");
        assert_eq!(num(20_000.0), "20000");
        let mut issues = Vec::new();
        let mut c = Checker::new("navigation", &mut issues);
        c.within("dock_length_m", 1e300, 0.0, 0.25, "m", "a reason");
        c.within("dock_length_m", 0.1, 0.0, 0.25, "m", "a reason");
        c.within_int("history_steps", 4_000_000_000u64, 2, 1000, "steps", "why");
        c.within_int("history_steps", 64u64, 2, 1000, "steps", "why");
        let text: Vec<String> = issues.iter().map(Issue::to_string).collect();
        assert_eq!(
            text,
            [
                "navigation.dock_length_m = 1e300: must be within 0 … 0.25 m (a reason)",
                "navigation.history_steps = 4000000000: must be within 2 … 1000 steps (why)",
            ]
        );
    }
}
