//! `robocog service list | info | call`: the services of a running graph, as `ros2 service`
//! offers them.
//!
//! Nothing needs to opt in: the services are read from the graph's liveliness tokens (each names
//! its request and reply types), a request given as JSON is laid over the request type's default
//! value and encoded through the registry of `interfaces`, and the reply is decoded the same way.
//!
//! Exit codes of `call`: 0 with a value (printed as JSON on stdout); 1 when the service answers an
//! error (its code and message on stderr), nobody serves it, or no reply comes in time; 2 when the
//! request itself is wrong (not JSON, a field the type does not have, a bad service name).

use interfaces::bus::CallError;
use interfaces::liveliness::Token;
use interfaces::msg;
use interfaces::raw::RawReply;
use std::collections::BTreeMap;
use std::io::Write;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: interfaces::ConnectArgs,
    #[command(subcommand)]
    pub verb: Verb,
}

#[derive(Debug, clap::Subcommand)]
pub enum Verb {
    /// Every service of the namespace, with its request and reply types and who serves it.
    List {
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// A service's types, its servers, and the shapes of its request and reply.
    Info { service: String },
    /// Call a service with a request given as JSON and print the reply as one line of JSON.
    /// Fields left out take their default value; unknown fields are an error.
    /// Exit code: 0 with a reply, 1 when the service answers an error or none comes, 2 for a
    /// request that is not valid.
    Call {
        service: String,
        /// The request (default: the request type's default value).
        #[arg(default_value = "{}")]
        json: String,
        /// Wait at most this long for the reply (s).
        #[arg(long, default_value_t = 5.0)]
        timeout: f64,
        /// Indented JSON.
        #[arg(long)]
        pretty: bool,
    },
}

/// How long the graph's tokens are gathered.
const GRAPH_WAIT: Duration = Duration::from_millis(700);

/// One service of the graph, from its servers' tokens.
#[derive(Debug, Default, PartialEq)]
struct ServiceInfo {
    /// (request type, reply type), once each.
    types: Vec<(String, String)>,
    servers: Vec<String>,
}

fn services(tokens: &[Token]) -> BTreeMap<String, ServiceInfo> {
    let mut map: BTreeMap<String, ServiceInfo> = BTreeMap::new();
    for t in tokens {
        let Token::Service {
            component,
            request,
            reply,
            service,
        } = t
        else {
            continue;
        };
        let e = map.entry(service.clone()).or_default();
        let pair = (request.clone(), reply.clone());
        if !e.types.contains(&pair) {
            e.types.push(pair);
        }
        if !e.servers.contains(component) {
            e.servers.push(component.clone());
        }
    }
    map
}

fn check_service(name: &str) -> anyhow::Result<()> {
    super::topic::check_name("service", name)
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let bus = super::cli_bus(&args.connect).await?;
    match args.verb {
        Verb::List { json } => {
            let map = services(&bus.graph(GRAPH_WAIT).await?);
            if json {
                let v: Vec<_> = map
                    .iter()
                    .map(|(s, i)| {
                        serde_json::json!({
                            "service": s,
                            "request": i.types.iter().map(|t| &t.0).collect::<Vec<_>>(),
                            "reply": i.types.iter().map(|t| &t.1).collect::<Vec<_>>(),
                            "servers": i.servers,
                        })
                    })
                    .collect();
                out!("{}", serde_json::to_string_pretty(&v)?);
            } else if map.is_empty() {
                out!("no services in namespace {:?}", bus.namespace());
            } else {
                let w = map.keys().map(String::len).max().unwrap_or(7).max(7);
                out!(
                    "{:w$}  {:28}  {:28}  SERVERS",
                    "SERVICE",
                    "REQUEST",
                    "REPLY"
                );
                for (s, i) in &map {
                    let (req, rep): (Vec<&str>, Vec<&str>) = i
                        .types
                        .iter()
                        .map(|(a, b)| (a.as_str(), b.as_str()))
                        .unzip();
                    out!(
                        "{s:w$}  {:28}  {:28}  {}",
                        req.join("|"),
                        rep.join("|"),
                        i.servers.join(", ")
                    );
                }
            }
            Ok(0)
        }
        Verb::Info { service } => {
            if let Err(e) = check_service(&service) {
                eprintln!("error: {e}");
                return Ok(2);
            }
            let map = services(&bus.graph(GRAPH_WAIT).await?);
            let Some(info) = map.get(&service) else {
                eprintln!(
                    "no component of namespace {:?} serves {service:?}",
                    bus.namespace()
                );
                return Ok(1);
            };
            out!("service:  {service}");
            out!("servers:  {}", info.servers.join(", "));
            for (req, rep) in &info.types {
                out!("request:  {req}");
                out!("reply:    {rep}");
                for t in [req, rep] {
                    match msg::lookup(t) {
                        Ok(e) => out!(
                            "shape of {t}:\n{}",
                            serde_json::to_string_pretty(&(e.example)())?
                        ),
                        Err(e) => out!("{e}"),
                    }
                }
            }
            Ok(0)
        }
        Verb::Call {
            service,
            json,
            timeout,
            pretty,
        } => {
            if let Err(e) = check_service(&service) {
                eprintln!("error: {e}");
                return Ok(2);
            }
            if !(timeout.is_finite() && timeout > 0.0) {
                eprintln!("error: --timeout must be a number of seconds > 0, got {timeout}");
                return Ok(2);
            }
            let map = services(&bus.graph(GRAPH_WAIT).await?);
            let (req_type, rep_type) = match map.get(&service).map(|i| i.types.as_slice()) {
                Some([one]) => one.clone(),
                Some(many) if !many.is_empty() => {
                    eprintln!(
                        "error: {service} is served with different types ({}): its servers disagree",
                        many.iter()
                            .map(|(a, b)| format!("{a} -> {b}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    );
                    return Ok(1);
                }
                _ => {
                    eprintln!(
                        "no component of namespace {:?} serves {service:?}",
                        bus.namespace()
                    );
                    return Ok(1);
                }
            };
            let request = match request_payload(&req_type, &json) {
                Ok(p) => p,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    return Ok(2);
                }
            };
            let reply = bus
                .raw_call(
                    &service,
                    &req_type,
                    request,
                    Duration::from_secs_f64(timeout),
                )
                .await;
            match reply {
                Ok(RawReply::Ok(wire)) => {
                    let v = (msg::lookup(&rep_type)?.reply_to_json)(&wire).map_err(|e| {
                        anyhow::anyhow!("the reply of {service} does not decode as {rep_type}: {e}")
                    })?;
                    let s = if pretty {
                        serde_json::to_string_pretty(&v)?
                    } else {
                        v.to_string()
                    };
                    out!("{s}");
                    Ok(0)
                }
                Ok(RawReply::Err(e)) => {
                    eprintln!("{service} answered {:?}: {}", e.code, e.message);
                    Ok(1)
                }
                Err(e @ (CallError::NoServer(_) | CallError::Timeout { .. })) => {
                    eprintln!("{e}");
                    Ok(1)
                }
                Err(e) => Err(anyhow::anyhow!("calling {service}: {e}")),
            }
        }
    }
}

/// The request given as JSON, over the type's default value, encoded.
fn request_payload(type_name: &str, json: &str) -> anyhow::Result<Vec<u8>> {
    let entry = msg::lookup(type_name)?;
    let given: serde_json::Value =
        serde_json::from_str(json).map_err(|e| anyhow::anyhow!("the request is not JSON: {e}"))?;
    let mut value = (entry.example)();
    super::topic::merge(&mut value, &given, type_name, "")?;
    Ok((entry.from_json)(value)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn services_are_gathered_from_the_tokens() {
        let svc = |component: &str, req: &str| Token::Service {
            component: component.into(),
            request: req.into(),
            reply: "robocog.Text".into(),
            service: "echo".into(),
        };
        let tokens = [
            svc("a", "robocog.Text"),
            svc("b", "robocog.Text"),
            svc("b", "robocog.Text"),
            Token::Publisher {
                component: "a".into(),
                type_name: "robocog.Text".into(),
                topic: "chatter".into(),
            },
        ];
        let map = services(&tokens);
        assert_eq!(map.len(), 1);
        assert_eq!(
            map["echo"],
            ServiceInfo {
                types: vec![("robocog.Text".into(), "robocog.Text".into())],
                servers: vec!["a".into(), "b".into()],
            }
        );
    }

    #[test]
    fn a_request_is_laid_over_the_default_and_wrong_fields_are_named() {
        let p = request_payload("robocog.Text", r#"{"text": "hi"}"#).unwrap();
        let v = (msg::lookup("robocog.Text").unwrap().to_json)(&p).unwrap();
        assert_eq!(v["text"], "hi");
        assert_eq!(v["header"]["seq"], 0);
        let e = request_payload("robocog.Text", r#"{"txt": "hi"}"#).unwrap_err();
        assert!(e.to_string().contains("no field \"txt\""), "{e}");
        let e = request_payload("robocog.Text", "hi").unwrap_err();
        assert!(e.to_string().contains("not JSON"), "{e}");
        let e = request_payload("robocog.Nope", "{}").unwrap_err();
        assert!(e.to_string().contains("unknown message type"), "{e}");
    }
}
