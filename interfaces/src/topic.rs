//! Typed topic and service names.
//!
//! A [`Topic<T>`] is a name plus the message type it carries; a [`Service<Req, Rep>`] a name plus
//! its request and reply types. Components only ever name topics through the constants of
//! [`crate::topics`], so a misspelt topic or a wrong message type does not compile. Names are
//! checked when the constant is built: an invalid character is a compile-time error.
//!
//! On the wire, under a namespace `ns`:
//!
//! | what | zenoh key |
//! |---|---|
//! | topic `vision/ball` | `robocog/<ns>/t/vision/ball` |
//! | service `dr/transform` | `robocog/<ns>/s/dr/transform` |
//! | liveliness tokens | `robocog/<ns>/_live/...` (see [`crate::liveliness`]) |

use std::marker::PhantomData;

/// Characters allowed in topic, service, component and namespace names.
const fn valid_char(c: u8, slash: bool) -> bool {
    c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'_' || c == b'-' || (slash && c == b'/')
}

/// Panics (at compile time, in a `const`) when `name` is not a valid topic or service name:
/// lowercase ASCII, digits, `_`, `-`, and `/` between non-empty chunks.
pub const fn check_name(name: &str) {
    let b = name.as_bytes();
    assert!(!b.is_empty(), "empty topic name");
    assert!(
        b[0] != b'/' && b[b.len() - 1] != b'/',
        "topic names neither start nor end with '/'"
    );
    let mut i = 0;
    while i < b.len() {
        assert!(valid_char(b[i], true), "topic names use [a-z0-9_-/] only");
        assert!(
            !(b[i] == b'/' && i + 1 < b.len() && b[i + 1] == b'/'),
            "empty chunk in name"
        );
        i += 1;
    }
}

/// Whether `s` is a valid namespace or component name (`[A-Za-z0-9_-]+`, no `/`).
pub fn is_valid_segment(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|c| valid_char(c.to_ascii_lowercase(), false) || c == b'.')
        && !s.starts_with('.')
}

/// Whether `s` is a valid topic or service name (what [`check_name`] accepts), for names typed
/// by users at run time.
pub fn is_valid_name(s: &str) -> bool {
    let b = s.as_bytes();
    !b.is_empty()
        && b[0] != b'/'
        && b[b.len() - 1] != b'/'
        && !s.contains("//")
        && b.iter().all(|&c| valid_char(c, true))
}

/// A topic: a name and the message type published on it.
pub struct Topic<T> {
    name: &'static str,
    _type: PhantomData<fn() -> T>,
}

impl<T> Topic<T> {
    /// A topic named `name`; an invalid name fails to compile when used in a `const`.
    pub const fn new(name: &'static str) -> Self {
        check_name(name);
        Self {
            name,
            _type: PhantomData,
        }
    }
    pub const fn name(&self) -> &'static str {
        self.name
    }
}

impl<T> Clone for Topic<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Topic<T> {}
impl<T> std::fmt::Debug for Topic<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Topic({})", self.name)
    }
}

/// A service: a name, its request type and its reply type.
pub struct Service<Req, Rep> {
    name: &'static str,
    _types: PhantomData<fn(Req) -> Rep>,
}

impl<Req, Rep> Service<Req, Rep> {
    pub const fn new(name: &'static str) -> Self {
        check_name(name);
        Self {
            name,
            _types: PhantomData,
        }
    }
    pub const fn name(&self) -> &'static str {
        self.name
    }
}

impl<Req, Rep> Clone for Service<Req, Rep> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<Req, Rep> Copy for Service<Req, Rep> {}
impl<Req, Rep> std::fmt::Debug for Service<Req, Rep> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Service({})", self.name)
    }
}

/// The zenoh key of topic `name` in namespace `ns`.
pub fn topic_key(ns: &str, name: &str) -> String {
    format!("robocog/{ns}/t/{name}")
}

/// The topic name a zenoh key of namespace `ns` names (`robocog/<ns>/t/vision/ball` gives
/// `vision/ball`); `None` for a key that is not one of the namespace's topics.
pub fn topic_name<'k>(ns: &str, key: &'k str) -> Option<&'k str> {
    let name = key
        .strip_prefix("robocog/")?
        .strip_prefix(ns)?
        .strip_prefix("/t/")?;
    (!name.is_empty()).then_some(name)
}

/// Whether `s` is a valid topic pattern: a topic name whose chunks may also be `*` (any one
/// chunk) or `**` (any number of chunks), e.g. `**` (every topic) or `vision/*`.
pub fn is_valid_pattern(s: &str) -> bool {
    !s.is_empty()
        && s.split('/').all(|chunk| {
            chunk == "*" || chunk == "**" || (!chunk.is_empty() && is_valid_name(chunk))
        })
}

/// The zenoh key of service `name` in namespace `ns`.
pub fn service_key(ns: &str, name: &str) -> String {
    format!("robocog/{ns}/s/{name}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        assert!(is_valid_name("vision/ball"));
        assert!(!is_valid_name("vision//ball"));
        assert!(!is_valid_name("/vision"));
        assert!(!is_valid_name("Vision"));
        assert!(!is_valid_name("a*b"));
        assert!(is_valid_segment("test-1a2b"));
        assert!(!is_valid_segment("a/b"));
        assert!(!is_valid_segment(""));
        assert_eq!(topic_key("ns1", "vision/ball"), "robocog/ns1/t/vision/ball");
        assert!(is_valid_pattern("**"));
        assert!(is_valid_pattern("vision/*"));
        assert!(is_valid_pattern("vision/ball"));
        assert!(!is_valid_pattern("vision/**ball"));
        assert!(!is_valid_pattern("vision//ball"));
        assert!(!is_valid_pattern(""));
    }

    #[test]
    fn topic_names_come_back_from_keys() {
        let key = topic_key("ns1", "vision/ball");
        assert_eq!(topic_name("ns1", &key), Some("vision/ball"));
        assert_eq!(topic_name("ns", &key), None);
        assert_eq!(topic_name("ns1", "robocog/ns1/s/dr/transform"), None);
        assert_eq!(topic_name("ns1", "robocog/ns1/t/"), None);
    }

    #[test]
    #[should_panic]
    fn an_invalid_name_is_refused() {
        let _ = Topic::<u8>::new("bad name");
    }
}
