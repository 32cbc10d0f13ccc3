//! The loopback router a deployment's components join (hosted by `robocog launch`, and by
//! benchmarks that need a bus of their own).

use crate::bus::BusError;

/// Open a zenoh router listening on `listen` (`tcp/127.0.0.1:0` for any free port), with
/// multicast scouting off. Returns the session and the TCP endpoint it actually listens on.
pub async fn open_router(listen: &str) -> Result<(zenoh::Session, String), BusError> {
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
    let session = zenoh::open(config).await.map_err(|e| BusError::Connect {
        endpoints: listen.to_string(),
        reason: format!("cannot start a router: {e}"),
    })?;
    let endpoint = session
        .info()
        .locators()
        .await
        .into_iter()
        .map(|l| l.to_string())
        .find(|l| l.starts_with("tcp/"))
        .ok_or_else(|| BusError::Config(format!("the router on {listen} has no TCP endpoint")))?;
    Ok((session, endpoint))
}
