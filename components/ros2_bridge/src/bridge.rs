//! The bridge's loop: robocog's graph out to ROS 2, ROS 2 publishers in to robocog.
//!
//! **Out.** For every topic a robocog component publishes (its liveliness token), when its type
//! has a ROS 2 definition: a node token per publishing component (the ROS 2 node of that name),
//! a publisher token per (component, topic), and a zenoh publisher on the topic's rmw_zenoh key
//! fed by a subscription to the robocog topic: each sample goes out as it is, with the
//! attachment ROS 2 subscribers need. `ros2 topic list` and `ros2 topic echo` see it.
//!
//! **In.** For every ROS 2 publisher token (another zenoh session's) of a type robocog knows,
//! with robocog's type hash: a subscription to its key; each sample with a well-formed
//! attachment and a payload that decodes is published on the robocog topic of the same name.
//! What is refused is counted on `diagnostics` (`ros2_unknown_type/<topic>`,
//! `ros2_type_mismatch/<topic>`, `ros2_bad_hash/<topic>`, `ros2_bad_attachment/<topic>`,
//! `ros2_undecodable/<topic>`, `ros2_dropped/<topic>`) and logged, rate-limited.
//!
//! Both directions subscribe to remote samples only, so what the bridge itself publishes on one
//! side never comes back to it from the other.

use crate::wire::{self, Attachment, Kind};
use interfaces::Bus;
use interfaces::Shutdown;
use interfaces::bus::Counters;
use interfaces::liveliness::{self, Token};
use interfaces::ratelimit::RateLimiter;
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::CongestionControl;
use zenoh::sample::{Locality, Sample, SampleKind};

/// What the bridge does (from the command line).
#[derive(Debug, Clone)]
pub struct Settings {
    /// The ROS 2 domain (ROS_DOMAIN_ID).
    pub domain: u32,
    /// robocog topics never bridged out.
    pub exclude: Vec<String>,
}

/// Samples waiting to go onto a robocog topic.
const INBOUND_QUEUE: usize = 256;

/// One ROS 2 node the bridge announces: a robocog component that publishes.
struct Node {
    id: u64,
    _token: LivelinessToken,
}

/// One robocog topic going out to ROS 2.
struct Outbound {
    /// The publishing components, each with its publisher token.
    publishers: HashMap<String, LivelinessToken>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    ros_topic: String,
    dds_type: String,
    hash: String,
}

/// One ROS 2 topic coming in to robocog.
struct Inbound {
    /// The tokens of the ROS 2 publishers on it.
    publishers: BTreeSet<String>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _forwarder: tokio::task::JoinHandle<()>,
}

/// Counts and logs (rate-limited, per counter) what is refused.
#[derive(Clone)]
struct Refusals {
    counters: Arc<Counters>,
    limiters: Arc<Mutex<HashMap<String, RateLimiter>>>,
}

impl Refusals {
    #[expect(
        clippy::disallowed_methods,
        reason = "the log limiter paces what a person reads, on the wall"
    )]
    fn refuse(&self, counter: &str, why: &str) {
        self.counters.incr(counter);
        let mut l = self.limiters.lock().unwrap_or_else(|p| p.into_inner());
        let limiter = l
            .entry(counter.to_string())
            .or_insert_with(|| RateLimiter::new(Duration::from_secs(5)));
        if let Some(suppressed) = limiter.allow(Instant::now()) {
            tracing::warn!("{why} ({counter}; {suppressed} more not logged)");
        }
    }
}

struct Bridge {
    bus: Bus,
    settings: Settings,
    zid: String,
    next_id: u64,
    nodes: HashMap<String, Node>,
    /// By (topic, type).
    outbound: HashMap<(String, String), Outbound>,
    /// By robocog topic.
    inbound: HashMap<String, Inbound>,
    /// Foreign tokens already refused (so each is counted once).
    refused_tokens: BTreeSet<String>,
    refusals: Refusals,
}

/// Run the bridge until `shutdown`.
pub async fn run(bus: Bus, settings: Settings, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let session = bus.session().clone();
    let robocog_graph = session
        .liveliness()
        .declare_subscriber(liveliness::all(bus.namespace()))
        .history(true)
        .await
        .map_err(|e| anyhow::anyhow!("watching the robocog graph: {e}"))?;
    let ros_graph_key = format!("{}/{}/**", wire::ADMIN_SPACE, settings.domain);
    let ros_graph = session
        .liveliness()
        .declare_subscriber(&ros_graph_key)
        .history(true)
        .await
        .map_err(|e| anyhow::anyhow!("watching the ROS 2 graph ({ros_graph_key}): {e}"))?;
    let refusals = Refusals {
        counters: bus.counters().clone(),
        limiters: Default::default(),
    };
    let mut bridge = Bridge {
        zid: session.zid().to_string(),
        bus,
        settings,
        next_id: 0,
        nodes: HashMap::new(),
        outbound: HashMap::new(),
        inbound: HashMap::new(),
        refused_tokens: BTreeSet::new(),
        refusals,
    };
    tracing::info!(
        "bridging namespace {} and ROS 2 domain {} (rmw_zenoh keys; this session's id {})",
        bridge.bus.namespace(),
        bridge.settings.domain,
        bridge.zid
    );
    loop {
        tokio::select! {
            _ = shutdown.wait() => break,
            s = robocog_graph.recv_async() => match s {
                Ok(s) => bridge.robocog_token(&s).await,
                Err(_) => anyhow::bail!("the robocog graph's token subscription closed"),
            },
            s = ros_graph.recv_async() => match s {
                Ok(s) => bridge.ros_token(&s).await,
                Err(_) => anyhow::bail!("the ROS 2 graph's token subscription closed"),
            },
        }
    }
    Ok(())
}

impl Bridge {
    fn next_id(&mut self) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        id
    }

    async fn declare_token(&self, key: &str) -> Option<LivelinessToken> {
        match self.bus.session().liveliness().declare_token(key).await {
            Ok(t) => Some(t),
            Err(e) => {
                tracing::warn!("cannot declare the ROS 2 token {key}: {e}");
                None
            }
        }
    }

    /// A robocog publisher appeared or left.
    async fn robocog_token(&mut self, s: &Sample) {
        let Some(Token::Publisher {
            component,
            type_name,
            topic,
        }) = liveliness::parse(self.bus.namespace(), s.key_expr().as_str())
        else {
            return;
        };
        if component == self.bus.component() || self.settings.exclude.contains(&topic) {
            return;
        }
        let key = (topic.clone(), type_name.clone());
        if s.kind() == SampleKind::Delete {
            if let Some(out) = self.outbound.get_mut(&key) {
                out.publishers.remove(&component);
                if out.publishers.is_empty() {
                    self.outbound.remove(&key);
                    tracing::info!("{topic}: no robocog publisher left; no longer bridged out");
                }
            }
            // A component that publishes nothing any more leaves ROS 2's graph as a node too.
            if !self
                .outbound
                .values()
                .any(|o| o.publishers.contains_key(&component))
            {
                self.nodes.remove(&component);
            }
            return;
        }
        let defs = ros_msgs::definitions();
        let (ros_name, hash) = match (defs.ros_name(&type_name), defs.rihs01(&type_name)) {
            (Ok(n), Ok(h)) => (n, h),
            (Err(why), _) | (_, Err(why)) => {
                if self.refused_tokens.insert(format!("{topic}/{type_name}")) {
                    tracing::info!("{topic} ({type_name}) is not bridged out: {why}");
                }
                return;
            }
        };
        let (Some(ros_topic), Some(dds_type)) =
            (wire::ros_topic(&topic), wire::dds_type_name(&ros_name))
        else {
            if self.refused_tokens.insert(format!("{topic}/{type_name}")) {
                tracing::info!("{topic} is not bridged out: not a ROS 2 topic name");
            }
            return;
        };
        if !self.outbound.contains_key(&key) {
            match self
                .open_outbound(&topic, &ros_topic, &dds_type, &hash)
                .await
            {
                Ok(out) => {
                    tracing::info!(
                        "{topic} ({type_name}) bridged out as {ros_topic} ({ros_name}, {hash})"
                    );
                    self.outbound.insert(key.clone(), out);
                }
                Err(e) => {
                    tracing::warn!("{topic} cannot be bridged out: {e:#}");
                    return;
                }
            }
        }
        // The component as a ROS 2 node, and its publisher.
        let node_id = match self.nodes.get(&component) {
            Some(n) => n.id,
            None => {
                let id = self.next_id();
                let token = wire::node_token(self.settings.domain, &self.zid, id, &component);
                let Some(t) = self.declare_token(&token).await else {
                    return;
                };
                self.nodes.insert(component.clone(), Node { id, _token: t });
                id
            }
        };
        let already = self
            .outbound
            .get(&key)
            .is_some_and(|o| o.publishers.contains_key(&component));
        if already {
            return;
        }
        let entity_id = self.next_id();
        let Some(out) = self.outbound.get(&key) else {
            return;
        };
        let token = wire::entity_token(
            self.settings.domain,
            &self.zid,
            node_id,
            entity_id,
            Kind::Publisher,
            &component,
            &out.ros_topic,
            &out.dds_type,
            &out.hash,
        );
        if let Some(t) = self.declare_token(&token).await
            && let Some(out) = self.outbound.get_mut(&key)
        {
            out.publishers.insert(component, t);
        }
    }

    /// The zenoh publisher on the topic's rmw_zenoh key, fed by robocog's topic.
    async fn open_outbound(
        &mut self,
        topic: &str,
        ros_topic: &str,
        dds_type: &str,
        hash: &str,
    ) -> anyhow::Result<Outbound> {
        let session = self.bus.session();
        let key = wire::data_key(self.settings.domain, ros_topic, dds_type, hash);
        // As rmw_zenoh publishes a volatile, keep-last topic: a congested link drops.
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .await
            .map_err(|e| anyhow::anyhow!("declaring a publisher on {key}: {e}"))?;
        // One GID for what goes out on this key: the route's, from its key.
        let gid = wire::gid(&key);
        let sequence = Arc::new(AtomicI64::new(1));
        let sent = self.bus.counters().counter(&format!("ros2_out/{topic}"));
        let failed = self.refusals.clone();
        let failed_name = format!("ros2_out_failed/{topic}");
        let subscriber = session
            .declare_subscriber(self.bus.topic_key(topic))
            .allowed_origin(Locality::Remote)
            .callback(move |sample| {
                // The source time stamp is the robocog publisher's, when its sample has one.
                let source_timestamp_ns = sample
                    .attachment()
                    .and_then(|a| Attachment::decode(&a.to_bytes()).ok())
                    .map_or_else(interfaces::header::system_now_ns, |a| a.source_timestamp_ns);
                let attachment = Attachment {
                    sequence: sequence.fetch_add(1, Ordering::Relaxed),
                    source_timestamp_ns,
                    gid,
                };
                match publisher
                    .put(sample.payload().clone())
                    .attachment(attachment.encode().to_vec())
                    .wait()
                {
                    Ok(()) => {
                        sent.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(e) => failed.refuse(&failed_name, &format!("cannot put on {key}: {e}")),
                }
            })
            .await
            .map_err(|e| anyhow::anyhow!("subscribing to {topic}: {e}"))?;
        Ok(Outbound {
            publishers: HashMap::new(),
            _subscriber: subscriber,
            ros_topic: ros_topic.to_string(),
            dds_type: dds_type.to_string(),
            hash: hash.to_string(),
        })
    }

    /// A ROS 2 entity appeared or left.
    async fn ros_token(&mut self, s: &Sample) {
        let token = s.key_expr().as_str().to_string();
        let Some(entity) = wire::parse_entity(&token) else {
            return;
        };
        if entity.zid == self.zid || entity.kind != Kind::Publisher {
            return;
        }
        let Some(topic) = entity.topic.strip_prefix('/').map(str::to_string) else {
            return;
        };
        if s.kind() == SampleKind::Delete {
            if let Some(i) = self.inbound.get_mut(&topic) {
                i.publishers.remove(&token);
                if i.publishers.is_empty() {
                    self.inbound.remove(&topic);
                    tracing::info!("{topic}: no ROS 2 publisher left; no longer bridged in");
                }
            }
            return;
        }
        if let Some(i) = self.inbound.get_mut(&topic) {
            i.publishers.insert(token);
            return;
        }
        let defs = ros_msgs::definitions();
        let type_name = wire::ros_type_name(&entity.dds_type)
            .and_then(|ros| defs.robocog_type(&ros))
            .filter(|_| interfaces::topic::is_valid_name(&topic));
        let Some(type_name) = type_name else {
            if self.refused_tokens.insert(token.clone()) {
                self.refusals.refuse(
                    &format!("ros2_unknown_type/{topic}"),
                    &format!(
                        "the ROS 2 publisher {} on {} publishes {}, which is not a robocog type (or the topic not a robocog name): not bridged in",
                        entity.node, entity.topic, entity.dds_type
                    ),
                );
            }
            return;
        };
        let ours = defs.rihs01(type_name).unwrap_or_default();
        if entity.hash != ours {
            if self.refused_tokens.insert(token.clone()) {
                self.refusals.refuse(
                    &format!("ros2_type_mismatch/{topic}"),
                    &format!(
                        "the ROS 2 publisher {} on {} has type hash {} where robocog's {} is {ours}: another definition, not bridged in",
                        entity.node, entity.topic, entity.hash, entity.dds_type
                    ),
                );
            }
            return;
        }
        match self.open_inbound(&topic, &entity, type_name, &ours).await {
            Ok(mut i) => {
                tracing::info!(
                    "the ROS 2 publisher {} on {} bridged in to {topic} ({type_name})",
                    entity.node,
                    entity.topic
                );
                i.publishers.insert(token);
                self.inbound.insert(topic, i);
            }
            Err(e) => tracing::warn!("{topic} cannot be bridged in: {e:#}"),
        }
    }

    async fn open_inbound(
        &mut self,
        topic: &str,
        entity: &wire::Entity,
        type_name: &'static str,
        hash: &str,
    ) -> anyhow::Result<Inbound> {
        let entry = interfaces::msg::lookup(type_name)?;
        let (tx, mut rx) = tokio::sync::mpsc::channel::<Vec<u8>>(INBOUND_QUEUE);
        // Any hash, so that a sample on a key of another hash is counted, not unseen.
        let key = format!(
            "{}/*",
            wire::data_key(self.settings.domain, &entity.topic, &entity.dds_type, "")
                .trim_end_matches('/')
        );
        let refusals = self.refusals.clone();
        let topic_name = topic.to_string();
        let hash = hash.to_string();
        let received = self.bus.counters().counter(&format!("ros2_in/{topic}"));
        let subscriber = self
            .bus
            .session()
            .declare_subscriber(key.clone())
            .allowed_origin(Locality::Remote)
            .callback(move |sample| {
                let t = &topic_name;
                let key = sample.key_expr().as_str();
                if !key.ends_with(&format!("/{hash}")) {
                    refusals.refuse(
                        &format!("ros2_bad_hash/{t}"),
                        &format!("a sample on {key}: not robocog's type hash {hash}"),
                    );
                    return;
                }
                match sample.attachment().map(|a| a.to_bytes()) {
                    None => {
                        refusals.refuse(
                            &format!("ros2_bad_attachment/{t}"),
                            &format!("a sample on {key} without the attachment rmw_zenoh puts on every sample"),
                        );
                        return;
                    }
                    Some(a) => {
                        if let Err(why) = Attachment::decode(&a) {
                            refusals.refuse(
                                &format!("ros2_bad_attachment/{t}"),
                                &format!("a sample on {key} with a malformed attachment: {why}"),
                            );
                            return;
                        }
                    }
                }
                let payload = sample.payload().to_bytes().into_owned();
                if let Err(e) = (entry.to_json)(&payload) {
                    refusals.refuse(
                        &format!("ros2_undecodable/{t}"),
                        &format!("a sample on {key} does not decode: {e}"),
                    );
                    return;
                }
                received.fetch_add(1, Ordering::Relaxed);
                if tx.try_send(payload).is_err() {
                    refusals.refuse(
                        &format!("ros2_dropped/{t}"),
                        &format!("{t}: robocog's side is behind; a sample from ROS 2 dropped"),
                    );
                }
            })
            .await
            .map_err(|e| anyhow::anyhow!("subscribing to {key}: {e}"))?;
        // The robocog publisher last: its token says the topic is bridged in, with the
        // subscription already declared (what arrives meanwhile waits in the queue).
        let publisher = self
            .bus
            .raw_publisher(topic, type_name, self.bus.component())
            .await
            .map_err(|e| anyhow::anyhow!("declaring {topic} on robocog's side: {e}"))?;
        let forwarder = tokio::spawn(async move {
            while let Some(payload) = rx.recv().await {
                if let Err(e) = publisher.put(payload).await {
                    tracing::warn!("cannot publish on {}: {e}", publisher.topic());
                }
            }
        });
        Ok(Inbound {
            publishers: BTreeSet::new(),
            _subscriber: subscriber,
            _forwarder: forwarder,
        })
    }
}
