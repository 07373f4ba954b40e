//! The control token: random at start-up, printed by `ratf` as part of the page's URL,
//! compared in constant time, so nobody else on the venue's Wi-Fi can drive the robot.

use std::fmt;

/// Bytes of randomness in a token (128 bits).
const TOKEN_BYTES: usize = 16;

/// A control token (lower-case hex).
#[derive(Clone, PartialEq, Eq)]
pub struct Token(String);

/// The operating system gave no random bytes.
#[derive(Debug, thiserror::Error)]
#[error("no random bytes for the HMI's token from the operating system: {0}")]
pub struct TokenError(String);

impl Token {
    /// A fresh random token from the operating system's generator.
    pub fn random() -> Result<Self, TokenError> {
        let mut bytes = [0u8; TOKEN_BYTES];
        getrandom::fill(&mut bytes).map_err(|e| TokenError(e.to_string()))?;
        Ok(Self(bytes.iter().map(|b| format!("{b:02x}")).collect()))
    }

    /// A token with this text (tests, or a team that sets its own).
    pub fn from_text(text: &str) -> Self {
        Self(text.to_owned())
    }

    /// The token's text, as it goes in the URL.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// True when `offered` is this token; the time taken does not depend on where the two
    /// first differ (only on their lengths).
    pub fn matches(&self, offered: &str) -> bool {
        let (a, b) = (self.0.as_bytes(), offered.as_bytes());
        let mut difference = u8::from(a.len() != b.len());
        for (i, &x) in a.iter().enumerate() {
            difference |= x ^ b.get(i).copied().unwrap_or(0);
        }
        difference == 0
    }
}

impl fmt::Debug for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never in logs by accident.
        f.write_str("Token(…)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_random_hex_and_match_only_themselves() {
        let a = Token::random().unwrap();
        let b = Token::random().unwrap();
        assert_ne!(a, b);
        assert_eq!(a.as_str().len(), 2 * TOKEN_BYTES);
        assert!(a.as_str().bytes().all(|c| c.is_ascii_hexdigit()));
        assert!(a.matches(a.as_str()));
        assert!(!a.matches(b.as_str()));
        assert!(!a.matches(""));
        assert!(!a.matches(&a.as_str()[1..]));
        assert!(!a.matches(&format!("{}0", a.as_str())));
        assert!(!format!("{a:?}").contains(a.as_str()));
    }
}
