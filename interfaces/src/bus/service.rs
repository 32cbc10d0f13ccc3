//! Services: [`Bus::serve`], [`Bus::call`], and their typed errors.

use super::*;

impl Bus {
    /// Serve `service`: every request is decoded and handed to `handler`, whose result (or typed
    /// error) goes back to the caller. A request that does not decode gets a `BadRequest` reply.
    pub async fn serve<Req, Rep, F, Fut>(
        &self,
        service: &Service<Req, Rep>,
        handler: F,
    ) -> Result<ServiceHandle, BusError>
    where
        Req: Message,
        Rep: Message,
        F: Fn(Req) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<Rep, ServiceError>> + Send + 'static,
    {
        let name = service.name();
        let key = topic::service_key(self.namespace(), name);
        let queryable = self
            .inner
            .session
            .declare_queryable(key)
            .with(zenoh::handlers::FifoChannel::new(DEFAULT_QUEUE))
            .await
            .map_err(zerr(format!("serving {name}")))?;
        let token = self
            .token(liveliness::service_key(
                self.namespace(),
                self.component(),
                Req::TYPE_NAME,
                Rep::TYPE_NAME,
                name,
            ))
            .await?;
        let handler = Arc::new(handler);
        let bad_requests = self.inner.counters.counter(&format!("bad_requests/{name}"));
        let task = tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let handler = handler.clone();
                let bad_requests = bad_requests.clone();
                tokio::spawn(async move {
                    let request = match query.payload() {
                        Some(p) => codec::decode::<Req>(&p.to_bytes(), Req::TYPE_NAME)
                            .map_err(|e| ServiceError::bad_request(e.to_string())),
                        None => Err(ServiceError::bad_request("the request has no payload")),
                    };
                    let reply: WireReply<Rep> = match request {
                        Ok(req) => handler(req).await.into(),
                        Err(e) => {
                            bad_requests.fetch_add(1, Ordering::Relaxed);
                            Err::<Rep, _>(e).into()
                        }
                    };
                    match codec::encode(&reply, Rep::TYPE_NAME) {
                        Ok(bytes) => {
                            let key = query.key_expr().clone();
                            if let Err(e) = query.reply(key, bytes).await {
                                tracing::warn!("could not send a reply: {e}");
                            }
                        }
                        Err(e) => tracing::error!("could not encode a reply: {e}"),
                    }
                });
            }
        });
        self.service_ready(name).await?;
        Ok(ServiceHandle {
            task,
            _token: token,
        })
    }

    /// Call `service` with `request`, waiting at most `timeout` for the reply.
    pub async fn call<Req: Message, Rep: Message>(
        &self,
        service: &Service<Req, Rep>,
        request: &Req,
        timeout: Duration,
    ) -> Result<Rep, CallError> {
        let bytes = codec::encode(request, Req::TYPE_NAME).map_err(CallError::Codec)?;
        let reply = self
            .call_payload(service.name(), Req::TYPE_NAME, bytes, timeout)
            .await?;
        let wire: WireReply<Rep> =
            codec::decode(&reply, Rep::TYPE_NAME).map_err(CallError::Codec)?;
        match wire {
            WireReply::Ok(rep) => Ok(rep),
            WireReply::Err(e) => Err(CallError::Remote(e)),
        }
    }

    /// Send one request payload (already encoded, of type `req_type`) to service `name` and
    /// return the first reply's payload: a wire reply, decoded by [`Bus::call`] or
    /// [`crate::raw::decode_reply`].
    #[expect(
        clippy::disallowed_methods,
        reason = "a transport time-out, on the wall as zenoh's own query time-out is"
    )]
    pub(crate) async fn call_payload(
        &self,
        name: &str,
        req_type: &str,
        bytes: Vec<u8>,
        timeout: Duration,
    ) -> Result<Vec<u8>, CallError> {
        let started = Instant::now();
        let replies = self
            .inner
            .session
            .get(topic::service_key(self.namespace(), name))
            .payload(bytes)
            .encoding(crate::raw::encoding_for(req_type))
            .timeout(timeout)
            .await
            .map_err(|e| CallError::Zenoh(e.to_string()))?;
        let first =
            tokio::time::timeout(timeout + Duration::from_millis(200), replies.recv_async()).await;
        match first {
            Ok(Ok(reply)) => match reply.into_result() {
                Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                Err(e) => {
                    let why = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                    if why.eq_ignore_ascii_case("timeout") {
                        Err(CallError::Timeout {
                            service: name.to_string(),
                            timeout,
                        })
                    } else {
                        Err(CallError::Zenoh(why))
                    }
                }
            },
            // The reply channel closed with nothing in it: before the time-out, nobody serves
            // the service; at the time-out, somebody did not answer in time.
            Ok(Err(_)) if started.elapsed() + Duration::from_millis(20) < timeout => {
                Err(CallError::NoServer(name.to_string()))
            }
            Ok(Err(_)) | Err(_) => Err(CallError::Timeout {
                service: name.to_string(),
                timeout,
            }),
        }
    }
}

/// A served service; dropping it stops serving.
pub struct ServiceHandle {
    task: tokio::task::JoinHandle<()>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for ServiceHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ServiceHandle")
    }
}

impl Drop for ServiceHandle {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Why a service refused or failed a request; travels back to the caller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{code:?}: {message}")]
pub struct ServiceError {
    pub code: ErrorCode,
    pub message: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorCode {
    /// The request is malformed or its values are invalid.
    BadRequest,
    /// It names something that does not exist (a frame, a joint, a node).
    NotFound,
    /// Valid, but refused (a limit, a rule, an owner).
    Refused,
    /// The server failed.
    Internal,
}

impl ServiceError {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
        }
    }
    pub fn bad_request(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::BadRequest, message)
    }
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::NotFound, message)
    }
    pub fn refused(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::Refused, message)
    }
}

/// A reply on the wire: the value or the error (CDR: the variant index, a `u32`, then the
/// value or the [`ServiceError`]).
#[derive(Debug, Serialize, Deserialize)]
pub(crate) enum WireReply<T> {
    Ok(T),
    Err(ServiceError),
}

impl<T> From<Result<T, ServiceError>> for WireReply<T> {
    fn from(r: Result<T, ServiceError>) -> Self {
        match r {
            Ok(v) => WireReply::Ok(v),
            Err(e) => WireReply::Err(e),
        }
    }
}

/// Why a call failed.
#[derive(Debug, thiserror::Error)]
pub enum CallError {
    #[error("no component serves {0} in this namespace")]
    NoServer(String),
    #[error("{service} did not answer within {timeout:?}")]
    Timeout { service: String, timeout: Duration },
    #[error("the service answered with an error: {0}")]
    Remote(ServiceError),
    #[error(transparent)]
    Codec(CodecError),
    #[error("zenoh error: {0}")]
    Zenoh(String),
}
