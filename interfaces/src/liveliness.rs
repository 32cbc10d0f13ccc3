//! Liveliness tokens: how a running graph describes itself with no opt-in.
//!
//! Every component, publisher, subscriber and service declares a zenoh liveliness token whose key
//! says what it is. The token vanishes when the process dies (even by SIGKILL: the router notices
//! the closed session), so `robocog topic list` and `robocog component list` always show the live
//! graph, and the launcher knows a component is up when its token appears.
//!
//! | token | key |
//! |---|---|
//! | component | `robocog/<ns>/_live/c/<component>/<host>/<pid>/<since_ms>` |
//! | publisher | `robocog/<ns>/_live/p/<component>/<type>/<topic>` |
//! | subscriber | `robocog/<ns>/_live/s/<component>/<type>/<topic>` |
//! | service | `robocog/<ns>/_live/q/<component>/<request type>/<reply type>/<service>` |
//! | the graph is stopping | `robocog/<ns>/_live/stopping/<launcher's zenoh id>` |
//!
//! Topic names may hold `/`, so they come last; the other fields never do.

/// The key expression matching every token of namespace `ns`.
pub fn all(ns: &str) -> String {
    format!("robocog/{ns}/_live/**")
}

/// The key expression matching every component token of namespace `ns`.
pub fn components(ns: &str) -> String {
    format!("robocog/{ns}/_live/c/**")
}

pub fn component_key(ns: &str, component: &str, host: &str, pid: u32, since_ms: i64) -> String {
    format!("robocog/{ns}/_live/c/{component}/{host}/{pid}/{since_ms}")
}

pub fn publisher_key(ns: &str, component: &str, type_name: &str, topic: &str) -> String {
    format!("robocog/{ns}/_live/p/{component}/{type_name}/{topic}")
}

pub fn subscriber_key(ns: &str, component: &str, type_name: &str, topic: &str) -> String {
    format!("robocog/{ns}/_live/s/{component}/{type_name}/{topic}")
}

pub fn service_key(ns: &str, component: &str, req: &str, rep: &str, service: &str) -> String {
    format!("robocog/{ns}/_live/q/{component}/{req}/{rep}/{service}")
}

/// The token a launcher declares before it stops its graph's first component ([`Stopping`]).
pub fn stopping_key(ns: &str, launcher: &str) -> String {
    format!("robocog/{ns}/_live/stopping/{launcher}")
}

/// A parsed liveliness token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Token {
    Component {
        name: String,
        host: String,
        pid: u32,
        since_ms: i64,
    },
    Publisher {
        component: String,
        type_name: String,
        topic: String,
    },
    Subscriber {
        component: String,
        type_name: String,
        topic: String,
    },
    Service {
        component: String,
        request: String,
        reply: String,
        service: String,
    },
}

/// Parse a token key of namespace `ns`; `None` for anything that is not a well-formed robocog token
/// (a foreign or older process: ignored, not fatal).
pub fn parse(ns: &str, key: &str) -> Option<Token> {
    let rest = key.strip_prefix(&format!("robocog/{ns}/_live/"))?;
    let (kind, rest) = rest.split_once('/')?;
    match kind {
        "c" => {
            let f: Vec<&str> = rest.split('/').collect();
            if f.len() != 4 {
                return None;
            }
            Some(Token::Component {
                name: f[0].to_string(),
                host: f[1].to_string(),
                pid: f[2].parse().ok()?,
                since_ms: f[3].parse().ok()?,
            })
        }
        "p" | "s" => {
            let f: Vec<&str> = rest.splitn(3, '/').collect();
            if f.len() != 3 {
                return None;
            }
            let (component, type_name, topic) = (f[0].into(), f[1].into(), f[2].into());
            Some(if kind == "p" {
                Token::Publisher {
                    component,
                    type_name,
                    topic,
                }
            } else {
                Token::Subscriber {
                    component,
                    type_name,
                    topic,
                }
            })
        }
        "q" => {
            let f: Vec<&str> = rest.splitn(4, '/').collect();
            if f.len() != 4 {
                return None;
            }
            Some(Token::Service {
                component: f[0].into(),
                request: f[1].into(),
                reply: f[2].into(),
                service: f[3].into(),
            })
        }
        _ => None,
    }
}

/// The components subscribed to one topic ([`Readers::watch`]), or publishing on it
/// ([`Readers::watch_writers`]), kept current from their liveliness tokens. Tools (`robocog
/// record`, `topic echo`, the viewer) subscribe without a token and never count.
pub struct Readers {
    rx: tokio::sync::watch::Receiver<std::collections::BTreeSet<String>>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for Readers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Readers({:?})", self.now())
    }
}

impl Readers {
    /// Watch which components of `bus`'s namespace subscribe to `topic`.
    pub async fn watch<T: crate::msg::Message>(
        bus: &crate::Bus,
        topic: &crate::topic::Topic<T>,
    ) -> Result<Readers, crate::bus::BusError> {
        Self::watch_tokens(bus, topic.name(), 's').await
    }

    /// Watch which components of `bus`'s namespace publish on `topic` (a component that
    /// withdraws its publisher, as `audio_io` does while its microphone is lost, leaves).
    pub async fn watch_writers<T: crate::msg::Message>(
        bus: &crate::Bus,
        topic: &crate::topic::Topic<T>,
    ) -> Result<Readers, crate::bus::BusError> {
        Self::watch_tokens(bus, topic.name(), 'p').await
    }

    /// Watch the tokens of `kind` (`s` subscriber, `p` publisher) on the topic `name`.
    async fn watch_tokens(
        bus: &crate::Bus,
        name: &str,
        kind: char,
    ) -> Result<Readers, crate::bus::BusError> {
        let ns = bus.namespace().to_string();
        let (tx, rx) = tokio::sync::watch::channel(std::collections::BTreeSet::new());
        // One entry per token key (a component may hold several subscriptions of one topic).
        let keys: std::sync::Mutex<std::collections::BTreeMap<String, String>> = Default::default();
        let name = name.to_string();
        let subscriber = bus
            .session()
            .liveliness()
            .declare_subscriber(format!("robocog/{ns}/_live/{kind}/**"))
            .history(true)
            .callback(move |sample| {
                let key = sample.key_expr().as_str().to_string();
                let (component, topic) = match parse(&ns, &key) {
                    Some(Token::Subscriber {
                        component, topic, ..
                    }) if kind == 's' => (component, topic),
                    Some(Token::Publisher {
                        component, topic, ..
                    }) if kind == 'p' => (component, topic),
                    _ => return,
                };
                if topic != name {
                    return;
                }
                let mut keys = keys.lock().unwrap_or_else(|p| p.into_inner());
                match sample.kind() {
                    zenoh::sample::SampleKind::Put => keys.insert(key, component),
                    zenoh::sample::SampleKind::Delete => keys.remove(&key),
                };
                let now: std::collections::BTreeSet<String> = keys.values().cloned().collect();
                tx.send_if_modified(|set| {
                    let changed = *set != now;
                    *set = now;
                    changed
                });
            })
            .await
            .map_err(|e| crate::bus::BusError::Zenoh {
                what: "watching the topic's readers or writers".into(),
                reason: e.to_string(),
            })?;
        Ok(Readers {
            rx,
            _subscriber: subscriber,
        })
    }

    /// The components subscribed now.
    pub fn now(&self) -> std::collections::BTreeSet<String> {
        self.rx.borrow().clone()
    }

    /// Whether any of `names` is subscribed now.
    pub fn any_of(&self, names: &[String]) -> bool {
        let set = self.rx.borrow();
        names.iter().any(|n| set.contains(n))
    }

    /// Wait for the next change.
    pub async fn changed(&mut self) {
        if self.rx.changed().await.is_err() {
            std::future::pending::<()>().await;
        }
    }
}

/// Whether a launcher is stopping the graph of the bus's namespace: it declares a
/// [`stopping_key`] token before it stops the first component, so that the others do not take
/// their neighbours' leaving for a failure (a dialog would tell the person it cannot hear her
/// while the game shuts down). The launcher stops the first component only once its router has
/// the token, but a component may still see a neighbour leave a few milliseconds before it sees
/// the token (seen in the dialog, under load): act on a neighbour's leaving after a short grace,
/// as the dialog does (`dialogs::component::UNHEARD_GRACE_S`).
pub struct Stopping {
    rx: tokio::sync::watch::Receiver<bool>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for Stopping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Stopping({})", self.now())
    }
}

impl Stopping {
    /// Watch for a launcher stopping the graph of `bus`'s namespace.
    pub async fn watch(bus: &crate::Bus) -> Result<Stopping, crate::bus::BusError> {
        let (tx, rx) = tokio::sync::watch::channel(false);
        let keys: std::sync::Mutex<std::collections::BTreeSet<String>> = Default::default();
        let subscriber = bus
            .session()
            .liveliness()
            .declare_subscriber(format!("robocog/{}/_live/stopping/**", bus.namespace()))
            .history(true)
            .callback(move |sample| {
                let key = sample.key_expr().as_str().to_string();
                let mut keys = keys.lock().unwrap_or_else(|p| p.into_inner());
                match sample.kind() {
                    zenoh::sample::SampleKind::Put => keys.insert(key),
                    zenoh::sample::SampleKind::Delete => keys.remove(&key),
                };
                tx.send_replace(!keys.is_empty());
            })
            .await
            .map_err(|e| crate::bus::BusError::Zenoh {
                what: "watching for the graph stopping".into(),
                reason: e.to_string(),
            })?;
        Ok(Stopping {
            rx,
            _subscriber: subscriber,
        })
    }

    /// Whether a launcher is stopping the graph now.
    pub fn now(&self) -> bool {
        *self.rx.borrow()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_parse_back() {
        let k = publisher_key("n1", "ball_tracker", "robocog.BallPosition", "vision/ball");
        assert_eq!(
            parse("n1", &k),
            Some(Token::Publisher {
                component: "ball_tracker".into(),
                type_name: "robocog.BallPosition".into(),
                topic: "vision/ball".into()
            })
        );
        let k = component_key("n1", "dr", "host-a", 42, 1700);
        assert_eq!(
            parse("n1", &k),
            Some(Token::Component {
                name: "dr".into(),
                host: "host-a".into(),
                pid: 42,
                since_ms: 1700
            })
        );
        let k = service_key("n1", "dr", "robocog.A", "robocog.B", "dr/transform");
        assert!(matches!(parse("n1", &k), Some(Token::Service { .. })));
        assert_eq!(parse("n2", &k), None, "another namespace is not ours");
        assert_eq!(parse("n1", "robocog/n1/_live/c/x"), None);
        assert_eq!(parse("n1", "robocog/n1/_live/z/a/b/c"), None);
    }
}
