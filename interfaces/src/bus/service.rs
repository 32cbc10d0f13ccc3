//! Services: [`Bus::serve`], [`Bus::call`], and their typed errors.

use super::fair::{self, FairQueue};
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
        let handler = Arc::new(handler);
        let bad_requests = self
            .inner
            .counters
            .counter(&format!("bad_requests/{}", service.name()));
        let answer: Answer = Arc::new(move |query| {
            let handler = handler.clone();
            let bad_requests = bad_requests.clone();
            Box::pin(async move { answer(query, handler.as_ref(), &bad_requests).await })
        });
        self.serve_queries(service.name(), Req::TYPE_NAME, Rep::TYPE_NAME, answer)
            .await
    }

    /// Serve `name` with `answer`, which replies to each query: the fair queues, the time-outs
    /// of callers that gave up and the liveliness token of [`Bus::serve`], for any codec.
    pub(crate) async fn serve_queries(
        &self,
        name: &str,
        req_type: &str,
        rep_type: &str,
        answer: Answer,
    ) -> Result<ServiceHandle, BusError> {
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
                req_type,
                rep_type,
                name,
            ))
            .await?;
        let counters = self.inner.counters.clone();
        let service = name.to_string();
        let task = tokio::spawn(async move {
            let mut waiting = FairQueue::new(PER_CALLER_QUEUE);
            let slots = Arc::new(tokio::sync::Semaphore::new(MAX_IN_FLIGHT));
            loop {
                tokio::select! {
                    // Take every request off zenoh's queue at once, into its caller's.
                    biased;
                    query = queryable.recv_async() => {
                        let Ok(query) = query else { break };
                        let (caller, deadline_ns) = caller_of(&query);
                        if let Err(query) = waiting.push(&caller, (query, deadline_ns)) {
                            counters.incr(&format!("service_busy/{service}/{caller}"));
                            refuse_busy(&query.0, &caller).await;
                        }
                    }
                    slot = slots.clone().acquire_owned(), if !waiting.is_empty() => {
                        let Ok(slot) = slot else { break };
                        let Some((caller, (query, deadline_ns))) = waiting.pop() else {
                            continue;
                        };
                        // Its caller stopped waiting: no work, no reply.
                        if crate::clock::system_now_ns() > deadline_ns {
                            counters.incr(&format!("service_expired/{service}/{caller}"));
                            continue;
                        }
                        let answer = answer.clone();
                        tokio::spawn(async move {
                            let _slot = slot;
                            answer(query).await;
                        });
                    }
                }
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
            .attachment(fair::encode_caller(
                self.component(),
                crate::clock::system_now_ns()
                    .saturating_add(i64::try_from(timeout.as_nanos()).unwrap_or(i64::MAX)),
            ))
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

/// What replies to one query of a served service (see [`Bus::serve_queries`]).
pub(crate) type Answer = Arc<
    dyn Fn(zenoh::query::Query) -> std::pin::Pin<Box<dyn Future<Output = ()> + Send>> + Send + Sync,
>;

/// How many requests of one service are handled at once.
pub(super) const MAX_IN_FLIGHT: usize = 16;
/// How many requests of one caller may wait for a service; past it, the caller is told the
/// service is busy (and the refusal counted).
pub const PER_CALLER_QUEUE: usize = 32;
/// How long a request from a caller that does not say when it stops waiting may wait.
const FOREIGN_WAIT: Duration = Duration::from_secs(10);

/// Who sent `query` (its component, or [`fair::FOREIGN`]) and until when it waits for the reply.
fn caller_of(query: &zenoh::query::Query) -> (String, i64) {
    query
        .attachment()
        .and_then(|a| fair::decode_caller(&a.to_bytes()))
        .unwrap_or_else(|| {
            let wait = i64::try_from(FOREIGN_WAIT.as_nanos()).unwrap_or(i64::MAX);
            (
                fair::FOREIGN.to_string(),
                crate::clock::system_now_ns().saturating_add(wait),
            )
        })
}

/// Tells a caller past its share that the service is busy.
async fn refuse_busy(query: &zenoh::query::Query, caller: &str) {
    let bytes = crate::raw::encode_error_reply(ServiceError::refused(format!(
        "busy: {caller} already has {PER_CALLER_QUEUE} requests waiting for this service"
    )));
    let key = query.key_expr().clone();
    let _ = query.reply(key, bytes).await;
}

/// Decodes `query`, hands it to `handler` and sends the reply (a `BadRequest` for a request
/// that does not decode, counted).
async fn answer<Req, Rep, F, Fut>(query: zenoh::query::Query, handler: &F, bad_requests: &AtomicU64)
where
    Req: Message,
    Rep: Message,
    F: Fn(Req) -> Fut,
    Fut: Future<Output = Result<Rep, ServiceError>>,
{
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
