//! The loopback router a deployment's components join (hosted by `robocog launch`, and by
//! benchmarks that need a bus of their own).

use crate::bus::BusError;

/// Open a zenoh router listening on `listen` (`tcp/127.0.0.1:0` for any free port), with
/// multicast scouting off. Returns the session and the TCP endpoint it actually listens on.
pub async fn open_router(listen: &str) -> Result<(zenoh::Session, String), BusError> {
    open_configured(router_config(listen)?, listen).await
}

/// The configuration of a router listening on `listen`, with multicast scouting off.
pub fn router_config(listen: &str) -> Result<zenoh::Config, BusError> {
    let mut config = zenoh::Config::default();
    for (key, value) in [
        ("mode", "\"router\"".to_string()),
        ("scouting/multicast/enabled", "false".to_string()),
        (
            "listen/endpoints",
            serde_json::to_string(&[listen]).unwrap_or_default(),
        ),
    ] {
        config
            .insert_json5(key, &value)
            .map_err(|e| BusError::Config(format!("router {key}: {e}")))?;
    }
    Ok(config)
}

/// Open a router with `config` (listening on `listen`, among others). Returns the session and
/// the TCP endpoint its clients on this host join: a loopback one when it has one.
pub async fn open_configured(
    config: zenoh::Config,
    listen: &str,
) -> Result<(zenoh::Session, String), BusError> {
    let session = zenoh::open(config).await.map_err(|e| BusError::Connect {
        endpoints: listen.to_string(),
        reason: format!("cannot start a router: {e}"),
    })?;
    let tcp: Vec<String> = session
        .info()
        .locators()
        .await
        .into_iter()
        .map(|l| l.to_string())
        .filter(|l| l.starts_with("tcp/"))
        .collect();
    let endpoint = tcp
        .iter()
        .find(|l| l.starts_with("tcp/127.") || l.starts_with("tcp/[::1]"))
        .or_else(|| tcp.first())
        .cloned()
        .ok_or_else(|| BusError::Config(format!("the router on {listen} has no TCP endpoint")))?;
    Ok((session, endpoint))
}

/// How long a link between two machines' routers may stay silent before its far end counts as
/// gone (zenoh's default is 10 s): a machine that drops off is noticed within this.
pub const LINK_LEASE_MS: u64 = 3000;

/// How many camera frames (`vision/rgbd`) a second leave for another machine over TLS.
pub const REMOTE_CAMERA_HZ: f64 = 2.0;

/// The certificate files of one machine (mutual TLS between machines).
#[derive(Debug, Clone)]
pub struct TlsFiles {
    /// The graph's CA, which signed every machine's certificate.
    pub ca: std::path::PathBuf,
    /// This machine's certificate (common name: the machine's name; subject names: the host of
    /// its endpoint) and key.
    pub cert: std::path::PathBuf,
    pub key: std::path::PathBuf,
}

impl TlsFiles {
    /// Machine `machine`'s files in a graph's certificate folder: `ca.pem`, `<machine>.pem`,
    /// `<machine>.key` (what `robocog certs` writes).
    pub fn in_folder(folder: &std::path::Path, machine: &str) -> Self {
        Self {
            ca: folder.join("ca.pem"),
            cert: folder.join(format!("{machine}.pem")),
            key: folder.join(format!("{machine}.key")),
        }
    }

    /// The files that are not there.
    pub fn missing(&self) -> Vec<&std::path::Path> {
        [&self.ca, &self.cert, &self.key]
            .into_iter()
            .filter(|p| !p.is_file())
            .map(|p| p.as_path())
            .collect()
    }
}

/// One machine's router in a graph over several machines.
#[derive(Debug, Clone)]
pub struct MachineRouter {
    /// Where this machine's own components join, plain (`tcp/127.0.0.1:7447`).
    pub local_listen: String,
    /// Where the other machines' routers join this one (`tls/10.0.0.2:7447`).
    pub endpoint: String,
    /// The other machines' endpoints, dialled (and redialled when lost).
    pub peers: Vec<String>,
    /// Mutual TLS and access control between machines; `None`: plain TCP, no access control.
    pub tls: Option<TlsFiles>,
    /// Every machine of the graph: the certificates' common names the access control lets in.
    pub machines: Vec<String>,
    /// The graph's namespace: the only keys the access control lets through...
    pub namespace: String,
    /// ...with, when the graph runs the rmw_zenoh-compatible mode (`ros2_bridge`), the keys of
    /// its ROS 2 domain (`@ros2_lv/<domain>/**` and `<domain>/**`).
    pub ros2_domain: Option<u32>,
}

/// The zenoh configuration of a machine's router: it listens on loopback for its own components
/// and on its endpoint for the other machines, dials the other machines, keeps multicast
/// scouting and gossip off, notices a lost machine in [`LINK_LEASE_MS`], and with TLS asks every
/// other machine for a certificate of the graph's CA (and shows its own), lets through only the
/// graph's keys from loopback and from the graph's machines, and lets camera frames cross to
/// other machines at [`REMOTE_CAMERA_HZ`].
pub fn machine_router_config(r: &MachineRouter) -> Result<zenoh::Config, BusError> {
    let mut config = zenoh::Config::default();
    let mut set = |key: &str, value: String| -> Result<(), BusError> {
        config
            .insert_json5(key, &value)
            .map_err(|e| BusError::Config(format!("router {key}: {e}")))
    };
    set("mode", "\"router\"".into())?;
    set("scouting/multicast/enabled", "false".into())?;
    set("scouting/gossip/enabled", "false".into())?;
    set("listen/endpoints", json(&[&r.local_listen, &r.endpoint]))?;
    set("connect/endpoints", json(&r.peers))?;
    set("transport/link/tx/lease", LINK_LEASE_MS.to_string())?;
    if let Some(tls) = &r.tls {
        let path = |p: &std::path::Path| json(&p.display().to_string());
        set("transport/link/tls/root_ca_certificate", path(&tls.ca))?;
        set("transport/link/tls/listen_certificate", path(&tls.cert))?;
        set("transport/link/tls/listen_private_key", path(&tls.key))?;
        set("transport/link/tls/connect_certificate", path(&tls.cert))?;
        set("transport/link/tls/connect_private_key", path(&tls.key))?;
        set("transport/link/tls/enable_mtls", "true".into())?;
        set("transport/link/tls/verify_name_on_connect", "true".into())?;
        set(
            "access_control",
            access_control(&r.machines, &r.namespace, r.ros2_domain).to_string(),
        )?;
        set(
            "downsampling",
            serde_json::json!([{
                "id": "camera frames to other machines",
                "link_protocols": ["tls"],
                "flows": ["egress"],
                "messages": ["put"],
                "rules": [{
                    "key_expr": format!("robocog/{}/vision/rgbd", r.namespace),
                    "freq": REMOTE_CAMERA_HZ,
                }],
            }])
            .to_string(),
        )?;
    }
    Ok(config)
}

/// zenoh's access control for a graph: everything on the graph's keys (and its ROS 2 domain's)
/// from loopback and from the graph's machines (by their certificates' common names), nothing
/// else.
fn access_control(
    machines: &[String],
    namespace: &str,
    ros2_domain: Option<u32>,
) -> serde_json::Value {
    let mut keys = vec![format!("robocog/{namespace}/**")];
    if let Some(d) = ros2_domain {
        keys.push(format!("@ros2_lv/{d}/**"));
        keys.push(format!("{d}/**"));
    }
    serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [{
            "id": "graph",
            "permission": "allow",
            "flows": ["ingress", "egress"],
            "messages": [
                "put", "delete", "declare_subscriber", "query", "reply",
                "declare_queryable", "liveliness_token", "declare_liveliness_subscriber",
                "liveliness_query"
            ],
            "key_exprs": keys,
        }],
        "subjects": [
            { "id": "this machine", "interfaces": ["lo"] },
            { "id": "the graph's machines", "cert_common_names": machines },
        ],
        "policies": [{
            "rules": ["graph"],
            "subjects": ["this machine", "the graph's machines"],
        }],
    })
}

/// A value as JSON text, for the configuration's lists and strings.
fn json<T: serde::Serialize + ?Sized>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}
