//! The shared secret every call but health must present (`authorization: Bearer <secret>`):
//! one rule for what a secret is (at least 16 visible ASCII characters: one line, no
//! spaces, no control characters, what an HTTP/2 header carries), for the
//! coordinator that checks it and the worker and clients that send it. Compared in
//! constant time, so that timing says nothing about how much of a guess is right.

use std::path::Path;
use tonic::metadata::{Ascii, MetadataValue};
use tonic::{Request, Status};

/// The environment variable that may hold the secret instead of a file.
pub const SECRET_ENV: &str = "STRIDER_SECRET";

/// A shared secret.
#[derive(Clone)]
pub struct Secret(String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(..)")
    }
}

/// Why a secret could not be had.
#[derive(Debug, thiserror::Error)]
pub enum SecretError {
    /// The file could not be read.
    #[error("secret file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The secret is empty or too short.
    #[error("{0}: the secret must be at least 16 characters (one line, no spaces)")]
    TooShort(String),
    /// The secret holds a character a header cannot carry.
    #[error(
        "{origin}: the secret holds {found}, at character {at}; it must be visible ASCII \
         (letters, digits, punctuation: no control characters, no spaces, no accents)"
    )]
    NotVisible {
        /// Where it came from.
        origin: String,
        /// The character, escaped.
        found: String,
        /// Its position, from 1.
        at: usize,
    },
    /// Neither a file nor the environment gave one.
    #[error("no secret: pass --token-file FILE or set {SECRET_ENV}")]
    Missing,
}

impl Secret {
    /// A secret from text (a file's first line, trimmed).
    pub fn new(text: &str, origin: &str) -> Result<Self, SecretError> {
        let s = text.lines().next().unwrap_or("").trim();
        if s.chars().count() < 16 || s.contains(char::is_whitespace) {
            return Err(SecretError::TooShort(origin.into()));
        }
        // The header is `Bearer <secret>`: only visible ASCII travels as gRPC metadata.
        if let Some((i, c)) = s.chars().enumerate().find(|(_, c)| !c.is_ascii_graphic()) {
            return Err(SecretError::NotVisible {
                origin: origin.into(),
                found: c.escape_default().to_string(),
                at: i + 1,
            });
        }
        Ok(Self(s.to_string()))
    }

    /// From `file` if given, else from the environment.
    pub fn load(file: Option<&Path>) -> Result<Self, SecretError> {
        match file {
            Some(path) => {
                let text = std::fs::read_to_string(path).map_err(|source| SecretError::Read {
                    path: path.display().to_string(),
                    source,
                })?;
                Self::new(&text, &path.display().to_string())
            }
            None => match std::env::var(SECRET_ENV) {
                Ok(text) => Self::new(&text, SECRET_ENV),
                Err(_) => Err(SecretError::Missing),
            },
        }
    }

    /// A fresh random secret (for `run`, whose workers live in the same process).
    pub fn random() -> Self {
        use rand::Rng;
        let mut rng = rand::rng();
        Self(
            (0..32)
                .map(|_| format!("{:x}", rng.random_range(0..16u8)))
                .collect(),
        )
    }

    /// The metadata value a caller sends.
    pub fn header_value(&self) -> String {
        format!("Bearer {}", self.0)
    }

    /// Whether `presented` is this secret's header value, in time independent of where
    /// they differ.
    pub fn matches(&self, presented: &[u8]) -> bool {
        let expected = self.header_value();
        let expected = expected.as_bytes();
        let mut diff = u8::from(presented.len() != expected.len());
        for (i, e) in expected.iter().enumerate() {
            diff |= e ^ presented.get(i).copied().unwrap_or(0);
        }
        diff == 0
    }

    /// The header value as gRPC metadata.
    pub fn metadata(&self) -> MetadataValue<Ascii> {
        self.header_value()
            .parse()
            .expect("a secret is one line of visible characters")
    }
}

/// A tonic interceptor for clients: sends `secret` with every call. With none the calls
/// go without, and the coordinator refuses them saying the secret is missing, which is
/// what a worker started without one should hear.
pub fn client_interceptor(
    secret: Option<&Secret>,
) -> impl FnMut(Request<()>) -> Result<Request<()>, Status> + Clone {
    let header = secret.map(Secret::metadata);
    move |mut r: Request<()>| {
        if let Some(h) = &header {
            r.metadata_mut().insert("authorization", h.clone());
        }
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_exact_header_matches() {
        let s = Secret::new("0123456789abcdef\n", "test").unwrap();
        assert!(s.matches(b"Bearer 0123456789abcdef"));
        assert!(!s.matches(b"Bearer 0123456789abcdeg"));
        assert!(!s.matches(b"Bearer 0123456789abcdef0"));
        assert!(!s.matches(b"Bearer 0123456789abcde"));
        assert!(!s.matches(b""));
    }

    #[test]
    fn a_secret_a_header_cannot_carry_is_refused_when_read() {
        for (text, at) in [
            ("0123456789\u{1b}abcdefgh", 11),
            ("0123456789abcdef\u{7f}", 17),
            ("\u{e9}0123456789abcdef", 1),
            ("0123456789abcdef\u{0}", 17),
        ] {
            match Secret::new(text, "file") {
                Err(SecretError::NotVisible { at: a, .. }) => assert_eq!(a, at, "{text:?}"),
                other => panic!("{text:?}: {other:?}"),
            }
        }
        let e = Secret::new("0123456789\u{1b}abcdefgh", "s.txt").unwrap_err();
        assert!(e.to_string().contains("s.txt"), "{e}");
        assert!(e.to_string().contains("\\u{1b}"), "{e}");
    }

    #[test]
    fn every_secret_can_travel_as_metadata() {
        let s = Secret::new("refusals-secret-0123456789abcdef", "test").unwrap();
        assert_eq!(
            s.metadata().to_str().unwrap(),
            "Bearer refusals-secret-0123456789abcdef"
        );
        let _ = Secret::random().metadata();
    }

    #[test]
    fn short_secrets_are_refused() {
        assert!(Secret::new("short", "f").is_err());
        assert!(Secret::new("", "f").is_err());
        assert!(Secret::new("0123456789 abcdef", "f").is_err());
        assert!(!Secret::random().matches(Secret::random().header_value().as_bytes()));
    }
}
