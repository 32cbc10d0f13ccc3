//! `robocog topic list | echo | hz | info | pub`: look at and poke any running graph.
//!
//! Nothing needs to opt in: the tools read the graph from its liveliness tokens, and decode every
//! payload by the type name its sample carries (its encoding's schema), through the registry of
//! `interfaces`.

use interfaces::liveliness::Token;
use interfaces::msg;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use std::io::Write;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: interfaces::ConnectArgs,
    #[command(subcommand)]
    pub verb: Verb,
}

#[derive(Debug, clap::Subcommand)]
pub enum Verb {
    /// Every topic of the namespace, with its type, publishers and subscribers.
    List {
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Print each message of a topic as one line of JSON.
    Echo {
        topic: String,
        /// Stop after this many messages.
        #[arg(long)]
        count: Option<u64>,
        /// Give up (exit code 1) when no message arrives for this many seconds.
        #[arg(long)]
        timeout: Option<f64>,
        /// Indented JSON.
        #[arg(long)]
        pretty: bool,
        /// Print each message as a ROS 2 decoder reads it (`std_msgs/Header` with `stamp.sec`
        /// and `stamp.nanosec`, points as `x`, `y`, `z`, enums as integers; `robocog interface
        /// show TYPE` gives the definitions) instead of robocog's JSON.
        #[arg(long)]
        ros: bool,
    },
    /// Measure a topic's rate and the jitter of its intervals, once a second.
    Hz {
        topic: String,
        /// Number of most recent intervals the figures are computed over.
        #[arg(long, default_value_t = 100)]
        window: usize,
        /// Stop after this many seconds (default: run until interrupted).
        #[arg(long)]
        duration: Option<f64>,
        /// Print each report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// A topic's type, its publishers and subscribers, and the shape of its messages.
    Info { topic: String },
    /// Publish a message given as JSON. Fields left out take their default value; unknown fields
    /// are an error. The type is taken from the graph, or from --type.
    Pub {
        topic: String,
        json: String,
        /// The message type (e.g. robocog.Text), when no component of the graph uses the topic.
        #[arg(long = "type")]
        type_name: Option<String>,
        /// Publish this many times.
        #[arg(long, default_value_t = 1)]
        count: u64,
        /// At this rate (Hz).
        #[arg(long, default_value_t = 1.0)]
        rate: f64,
        /// Wait at most this long for a subscriber before publishing (s).
        #[arg(long, default_value_t = 3.0)]
        wait: f64,
    },
}

const GRAPH_WAIT: Duration = Duration::from_millis(700);

struct TopicInfo {
    types: Vec<String>,
    publishers: Vec<String>,
    subscribers: Vec<String>,
}

fn topics(tokens: &[Token]) -> BTreeMap<String, TopicInfo> {
    let mut map: BTreeMap<String, TopicInfo> = BTreeMap::new();
    for t in tokens {
        let (topic, component, type_name, is_pub) = match t {
            Token::Publisher {
                component,
                type_name,
                topic,
            } => (topic, component, type_name, true),
            Token::Subscriber {
                component,
                type_name,
                topic,
            } => (topic, component, type_name, false),
            _ => continue,
        };
        let e = map.entry(topic.clone()).or_insert(TopicInfo {
            types: vec![],
            publishers: vec![],
            subscribers: vec![],
        });
        if !e.types.contains(type_name) {
            e.types.push(type_name.clone());
        }
        let list = if is_pub {
            &mut e.publishers
        } else {
            &mut e.subscribers
        };
        if !list.contains(component) {
            list.push(component.clone());
        }
    }
    map
}

pub(crate) fn check_topic(name: &str) -> anyhow::Result<()> {
    check_name("topic", name)
}

/// A topic's or a service's name (`kind`), checked.
pub(crate) fn check_name(kind: &str, name: &str) -> anyhow::Result<()> {
    if interfaces::topic::is_valid_name(name) {
        Ok(())
    } else {
        anyhow::bail!("invalid {kind} name {name:?}: lowercase letters, digits, '_', '-', '/'")
    }
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let bus = super::cli_bus(&args.connect).await?;
    match args.verb {
        Verb::List { json } => {
            let map = topics(&bus.graph(GRAPH_WAIT).await?);
            if json {
                let v: Vec<_> = map
                    .iter()
                    .map(|(t, i)| {
                        serde_json::json!({"topic": t, "types": i.types, "publishers": i.publishers, "subscribers": i.subscribers})
                    })
                    .collect();
                out!("{}", serde_json::to_string_pretty(&v)?);
            } else if map.is_empty() {
                out!("no topics in namespace {:?}", bus.namespace());
            } else {
                let w = map.keys().map(String::len).max().unwrap_or(5).max(5);
                out!(
                    "{:w$}  {:24}  {:>4}  {:>4}",
                    "TOPIC",
                    "TYPE",
                    "PUBS",
                    "SUBS"
                );
                for (t, i) in &map {
                    out!(
                        "{t:w$}  {:24}  {:>4}  {:>4}",
                        i.types.join("|"),
                        i.publishers.len(),
                        i.subscribers.len()
                    );
                }
            }
            Ok(0)
        }
        Verb::Info { topic } => {
            check_topic(&topic)?;
            let map = topics(&bus.graph(GRAPH_WAIT).await?);
            let Some(info) = map.get(&topic) else {
                eprintln!(
                    "no component of namespace {:?} uses topic {topic:?}",
                    bus.namespace()
                );
                return Ok(1);
            };
            out!("topic:       {topic}");
            out!("key:         {}", bus.topic_key(&topic));
            out!("type:        {}", info.types.join(" | "));
            out!("publishers:  {}", info.publishers.join(", "));
            out!("subscribers: {}", info.subscribers.join(", "));
            for t in &info.types {
                match msg::lookup(t) {
                    Ok(e) => out!(
                        "shape of {t}:\n{}",
                        serde_json::to_string_pretty(&(e.example)())?
                    ),
                    Err(e) => out!("{e}"),
                }
            }
            Ok(0)
        }
        #[expect(
            clippy::disallowed_methods,
            reason = "a command-line tool on the live bus: `--timeout` is the user's wait, on the wall"
        )]
        Verb::Echo {
            topic,
            count,
            timeout,
            pretty,
            ros,
        } => {
            check_topic(&topic)?;
            let sub = bus
                .raw_subscriber(&topic, 1024)
                .await
                .map_err(|e| anyhow::anyhow!("cannot subscribe to {topic}: {e}"))?;
            let mut printed = 0u64;
            let mut undecodable = 0u64;
            loop {
                let next = match timeout {
                    Some(t) => {
                        match tokio::time::timeout(Duration::from_secs_f64(t), sub.recv()).await {
                            Ok(r) => r,
                            Err(_) => {
                                eprintln!("no message on {topic} for {t} s");
                                return Ok(1);
                            }
                        }
                    }
                    None => sub.recv().await,
                };
                let Ok(sample) = next else { return Ok(1) };
                let bytes = sample.payload();
                let decoded = sample
                    .type_name
                    .as_deref()
                    .ok_or_else(|| "the sample names no type".to_string())
                    .and_then(|t| msg::lookup(t).map_err(|e| e.to_string()))
                    .and_then(|e| {
                        if ros {
                            return ros_msgs::definitions().ros_json(e.name, &bytes);
                        }
                        let mut v = (e.to_json)(&bytes).map_err(|e| e.to_string())?;
                        // The sequence number travels beside the payload.
                        if let (Some(seq), Some(h)) = (sample.seq, v.get_mut("header"))
                            && let Some(h) = h.as_object_mut()
                        {
                            h.insert("seq".into(), seq.into());
                        }
                        Ok(v)
                    });
                match decoded {
                    Ok(v) => {
                        let s = if pretty {
                            serde_json::to_string_pretty(&v)?
                        } else {
                            v.to_string()
                        };
                        out!("{s}");
                        printed += 1;
                        if count.is_some_and(|c| printed >= c) {
                            return Ok(0);
                        }
                    }
                    Err(e) => {
                        undecodable += 1;
                        eprintln!(
                            "undecodable payload #{undecodable} ({} bytes): {e}",
                            bytes.len()
                        );
                    }
                }
            }
        }
        #[expect(
            clippy::disallowed_methods,
            reason = "a command-line tool on the live bus: it measures the rate messages arrive at, on the wall"
        )]
        Verb::Hz {
            topic,
            window,
            duration,
            json,
        } => {
            check_topic(&topic)?;
            let sub = bus
                .raw_subscriber(&topic, 4096)
                .await
                .map_err(|e| anyhow::anyhow!("cannot subscribe to {topic}: {e}"))?;
            let started = Instant::now();
            let end = duration.map(|d| started + Duration::from_secs_f64(d));
            let mut stamps: std::collections::VecDeque<Instant> = Default::default();
            let mut report_at = started + Duration::from_secs(1);
            let mut total = 0u64;
            loop {
                let deadline = end.map_or(report_at, |e| e.min(report_at));
                match tokio::time::timeout_at(deadline.into(), sub.recv()).await {
                    Ok(Ok(_)) => {
                        total += 1;
                        stamps.push_back(Instant::now());
                        if stamps.len() > window + 1 {
                            stamps.pop_front();
                        }
                    }
                    Ok(Err(_)) => return Ok(1),
                    Err(_) => {}
                }
                let now = Instant::now();
                if now >= report_at {
                    report_at = now + Duration::from_secs(1);
                    if !print_rate(&topic, &stamps, total, json) {
                        return Ok(0);
                    }
                }
                if end.is_some_and(|e| now >= e) {
                    let _ = print_rate(&topic, &stamps, total, json);
                    return Ok(if total > 0 { 0 } else { 1 });
                }
            }
        }
        #[expect(
            clippy::disallowed_methods,
            reason = "a command-line tool on the live bus: its wait for a subscriber, its rate and its flush are the wall's"
        )]
        Verb::Pub {
            topic,
            json,
            type_name,
            count,
            rate,
            wait,
        } => {
            check_topic(&topic)?;
            let type_name = match type_name {
                Some(t) => t,
                None => {
                    let map = topics(&bus.graph(GRAPH_WAIT).await?);
                    match map.get(&topic).map(|i| i.types.as_slice()) {
                        Some([t]) => t.clone(),
                        Some(many) if !many.is_empty() => {
                            anyhow::bail!(
                                "topic {topic} carries several types ({}); pass --type",
                                many.join(", ")
                            )
                        }
                        _ => anyhow::bail!(
                            "no component of namespace {:?} uses topic {topic:?}; pass --type to publish anyway",
                            bus.namespace()
                        ),
                    }
                }
            };
            let entry = msg::lookup(&type_name)?;
            let given: serde_json::Value = serde_json::from_str(&json)
                .map_err(|e| anyhow::anyhow!("the message is not JSON: {e}"))?;
            let mut value = (entry.example)();
            merge(&mut value, &given, &type_name, "")?;
            let payload = (entry.from_json)(value)?;
            let publisher = bus
                .raw_publisher(&topic, &type_name, "robocog-cli")
                .await
                .map_err(|e| anyhow::anyhow!("cannot publish on {topic}: {e}"))?;
            // A one-shot publication is lost if nobody listens yet: wait for a subscriber.
            let until = Instant::now() + Duration::from_secs_f64(wait.max(0.0));
            loop {
                if publisher.has_subscribers().await {
                    break;
                }
                if Instant::now() >= until {
                    eprintln!(
                        "warning: no subscriber on {topic} after {wait} s; publishing anyway"
                    );
                    break;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            let period = Duration::from_secs_f64(1.0 / rate.max(1e-3));
            for i in 0..count {
                publisher
                    .put(payload.clone())
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                if i + 1 < count {
                    tokio::time::sleep(period).await;
                }
            }
            eprintln!("published {count} {type_name} on {topic}");
            // Give zenoh a moment to flush before the session closes.
            tokio::time::sleep(Duration::from_millis(100)).await;
            Ok(0)
        }
    }
}

/// Lay `given` over the default value `base`, refusing fields the type does not have.
pub(crate) fn merge(
    base: &mut serde_json::Value,
    given: &serde_json::Value,
    type_name: &str,
    path: &str,
) -> anyhow::Result<()> {
    use serde_json::Value;
    match (base, given) {
        (Value::Object(b), Value::Object(g)) => {
            for (k, v) in g {
                let here = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match b.get_mut(k) {
                    Some(slot) => merge(slot, v, type_name, &here)?,
                    None => {
                        let known: Vec<&str> = b.keys().map(String::as_str).collect();
                        anyhow::bail!(
                            "{type_name} has no field {here:?} (fields here: {})",
                            known.join(", ")
                        )
                    }
                }
            }
            Ok(())
        }
        (slot, v) => {
            *slot = v.clone();
            Ok(())
        }
    }
}

fn print_rate(
    topic: &str,
    stamps: &std::collections::VecDeque<Instant>,
    total: u64,
    json: bool,
) -> bool {
    let mut ok = true;
    if stamps.len() < 2 {
        if json {
            ok &= writeln!(
                std::io::stdout().lock(),
                "{}",
                serde_json::json!({"topic": topic, "messages": total, "rate_hz": 0.0})
            )
            .is_ok();
        } else {
            ok &= writeln!(
                std::io::stdout().lock(),
                "{topic}: {total} messages, not enough for a rate"
            )
            .is_ok();
        }
        return ok;
    }
    let intervals: Vec<f64> = stamps
        .iter()
        .zip(stamps.iter().skip(1))
        .map(|(a, b)| b.duration_since(*a).as_secs_f64())
        .collect();
    let n = intervals.len() as f64;
    let mean = intervals.iter().sum::<f64>() / n;
    let var = intervals.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let min = intervals.iter().copied().fold(f64::INFINITY, f64::min);
    let max = intervals.iter().copied().fold(0.0, f64::max);
    let rate = if mean > 0.0 { 1.0 / mean } else { 0.0 };
    if json {
        ok &= writeln!(std::io::stdout().lock(),
            "{}",
            serde_json::json!({"topic": topic, "messages": total, "rate_hz": rate, "min_s": min, "max_s": max, "jitter_std_s": var.sqrt(), "window": intervals.len()})
        ).is_ok();
    } else {
        ok &= writeln!(std::io::stdout().lock(),
            "{topic}: rate {rate:.2} Hz  min {min:.4} s  max {max:.4} s  jitter (std dev) {:.5} s  window {}",
            var.sqrt(),
            intervals.len()
        ).is_ok();
    }
    ok
}
