//! Validation helpers: each check names the full key path and the reason.

use std::fmt;

/// One invalid value: its full key path (e.g. `robot.wheel_diameter_m`) and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Issue {
    /// Full TOML key path.
    pub key: String,
    /// Why the value is rejected.
    pub reason: String,
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.key, self.reason)
    }
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

    /// Record an issue for `key` when `ok` is false.
    pub(crate) fn require(&mut self, key: &str, ok: bool, reason: impl FnOnce() -> String) {
        if !ok {
            self.issues.push(Issue {
                key: format!("{}.{key}", self.section),
                reason: reason(),
            });
        }
    }

    /// Finite and > 0.
    pub(crate) fn positive(&mut self, key: &str, value: f64) {
        self.require(key, value.is_finite() && value > 0.0, || {
            format!("must be a finite number > 0 (got {value})")
        });
    }

    /// Finite and ≥ 0.
    pub(crate) fn non_negative(&mut self, key: &str, value: f64) {
        self.require(key, value.is_finite() && value >= 0.0, || {
            format!("must be a finite number ≥ 0 (got {value})")
        });
    }

    /// Finite (any sign).
    pub(crate) fn finite(&mut self, key: &str, value: f64) {
        self.require(key, value.is_finite(), || {
            format!("must be a finite number (got {value})")
        });
    }

    /// Finite and within [lo, hi].
    pub(crate) fn within(&mut self, key: &str, value: f64, lo: f64, hi: f64) {
        self.require(key, value.is_finite() && (lo..=hi).contains(&value), || {
            format!("must be within [{lo}, {hi}] (got {value})")
        });
    }

    /// Not zero.
    pub(crate) fn nonzero(&mut self, key: &str, value: u64) {
        self.require(key, value != 0, || "must not be zero".to_owned());
    }

    /// Not empty after trimming.
    pub(crate) fn non_empty(&mut self, key: &str, value: &str) {
        self.require(key, !value.trim().is_empty(), || {
            "must not be empty".to_owned()
        });
    }
}
