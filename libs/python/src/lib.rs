//! `robocog._robocog`: the robocog runtime for components written in Python.
//!
//! The Python package `robocog` (this folder's `robocog/`) is a thin layer over this module; the
//! bus, the codec, the liveliness tokens, the counters and the clock are `interfaces`' own, so a
//! Python component is on the bus exactly as a Rust one is: it shows in `robocog component list`,
//! publishes `diagnostics`, counts what it drops, follows `--clock bus`.
//!
//! Threads: zenoh and the subscriptions run on a tokio runtime of the node's; every Python
//! callback (messages, requests, timers) runs on the thread that calls `Node.spin`, one at a
//! time, as rclpy's single-threaded executor does. A subscription's queue is the Rust
//! subscriber's (bounded, oldest dropped and counted): a slow callback never stalls zenoh.
#![allow(unsafe_code)] // `SampleBuffer::__getbuffer__`: the buffer protocol is a C API.

mod frompy;
mod topy;
mod types;

use interfaces::bus::{Bus, BusError, BusOptions, CallError, ServiceError};
use interfaces::clock::Clock;
use interfaces::node::{ClockSource, NodeArgs};
use pyo3::exceptions::{PyBufferError, PyRuntimeError, PyTimeoutError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pyo3::create_exception!(_robocog, RemoteError, pyo3::exceptions::PyException);
pyo3::create_exception!(_robocog, NoServerError, pyo3::exceptions::PyException);

/// What the callback thread is handed.
pub enum Event {
    /// A message, holding its subscription's turn until the callback has run.
    Message(
        Arc<SubscriptionInfo>,
        types::Delivery,
        tokio::sync::OwnedSemaphorePermit,
    ),
    Request {
        service: Arc<ServiceInfo>,
        payload: Vec<u8>,
        reply: tokio::sync::oneshot::Sender<Vec<u8>>,
    },
    Timer(usize),
    Shutdown,
}

/// A subscription, as the callback thread needs it.
pub struct SubscriptionInfo {
    pub topic: String,
    pub queue: usize,
    pub id: usize,
    /// Whether the callback takes the sequence number too: `callback(msg, seq)`.
    pub with_seq: bool,
}

/// A served service, as the callback thread needs it.
pub struct ServiceInfo {
    pub name: String,
    pub id: usize,
    pub request: &'static types::Ops,
    pub reply: &'static types::Ops,
}

fn bus_error(e: BusError) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

fn decode_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("the payload does not decode: {e}"))
}

/// A service's typed error as Python sees it: `RemoteError(code, message)`.
fn service_error(e: &ServiceError) -> PyErr {
    RemoteError::new_err((format!("{:?}", e.code), e.message.clone()))
}

/// A received payload lent to Python: a `bytes`-like object (buffer protocol) over the sample as
/// zenoh delivered it, shared memory included; `memoryview`s and NumPy arrays made from it keep
/// it, and the sample, alive.
#[pyclass(frozen, module = "robocog._robocog")]
pub struct SampleBuffer {
    pub payload: Box<dyn PayloadBytes + Send + Sync>,
}

/// Bytes that stay where they are for as long as their holder lives.
pub trait PayloadBytes {
    fn bytes(&self) -> &[u8];
    fn is_shm(&self) -> bool;
    /// The sample's sequence number (its attachment's).
    fn seq(&self) -> u64;
}

impl<T: interfaces::msg::Borrowable> PayloadBytes for interfaces::bus::Received<T> {
    fn bytes(&self) -> &[u8] {
        self.payload()
    }
    fn is_shm(&self) -> bool {
        interfaces::bus::Received::is_shm(self)
    }
    fn seq(&self) -> u64 {
        let mut view = self.view();
        T::view_header_mut(&mut view).seq
    }
}

#[pymethods]
impl SampleBuffer {
    fn __len__(&self) -> usize {
        self.payload.bytes().len()
    }

    /// Whether the payload is a shared-memory buffer (read in place, never copied).
    #[getter]
    fn is_shm(&self) -> bool {
        self.payload.is_shm()
    }

    /// # Safety
    /// Python's buffer protocol: `view` is the caller's `Py_buffer` to fill.
    unsafe fn __getbuffer__(
        slf: Bound<'_, Self>,
        view: *mut pyo3::ffi::Py_buffer,
        flags: std::os::raw::c_int,
    ) -> PyResult<()> {
        if flags & pyo3::ffi::PyBUF_WRITABLE == pyo3::ffi::PyBUF_WRITABLE {
            return Err(PyBufferError::new_err("a received sample is read-only"));
        }
        let bytes = slf.get().payload.bytes();
        // SAFETY: the bytes live as long as `slf`, which the view holds (FillInfo takes a
        // reference to it); the object is frozen, so they never change or move.
        let rc = unsafe {
            pyo3::ffi::PyBuffer_FillInfo(
                view,
                slf.as_ptr(),
                bytes.as_ptr() as *mut std::os::raw::c_void,
                bytes.len() as pyo3::ffi::Py_ssize_t,
                1,
                flags,
            )
        };
        if rc != 0 {
            return Err(PyErr::fetch(slf.py()));
        }
        Ok(())
    }

    unsafe fn __releasebuffer__(&self, _view: *mut pyo3::ffi::Py_buffer) {}
}

/// A publisher of one topic.
#[pyclass(frozen, module = "robocog._robocog")]
struct PyPublisher {
    inner: Box<dyn types::AnyPublisher>,
    rt: tokio::runtime::Handle,
    topic: String,
}

#[pymethods]
impl PyPublisher {
    /// Publish `msg` (plain values of the topic's type): stamped with the node's clock when its
    /// stamp is zero.
    fn publish(&self, py: Python<'_>, msg: &Bound<'_, PyAny>) -> PyResult<()> {
        self.inner.publish(py, msg, &self.rt)
    }

    #[getter]
    fn topic(&self) -> &str {
        &self.topic
    }
}

/// A component on the bus.
#[pyclass(frozen, module = "robocog._robocog")]
struct Node {
    rt: tokio::runtime::Runtime,
    bus: Bus,
    events_tx: flume::Sender<Event>,
    events: flume::Receiver<Event>,
    stopping: Arc<AtomicBool>,
    /// Callbacks by subscription, service and timer id.
    callbacks: std::sync::Mutex<HashMap<usize, Py<PyAny>>>,
    next_id: std::sync::atomic::AtomicUsize,
    tasks: std::sync::Mutex<Vec<tokio::task::JoinHandle<()>>>,
    keep: std::sync::Mutex<Vec<Box<dyn std::any::Any + Send>>>,
}

impl Node {
    fn id(&self) -> usize {
        self.next_id.fetch_add(1, Ordering::Relaxed)
    }

    fn keep_task(&self, t: tokio::task::JoinHandle<()>) {
        self.tasks.lock().unwrap_or_else(|p| p.into_inner()).push(t);
    }

    fn callback(&self, py: Python<'_>, id: usize) -> Option<Py<PyAny>> {
        self.callbacks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&id)
            .map(|c| c.clone_ref(py))
    }
}

#[pymethods]
impl Node {
    /// Join the bus as component `name` with the shared flags in `argv` (`--namespace`,
    /// `--connect`, `--clock`, `--name`, ...: `robocog._robocog.node_flags_help()`), announcing
    /// a component token once every service in `serves` is served.
    #[new]
    #[pyo3(signature = (name, argv, serves=Vec::new()))]
    fn new(py: Python<'_>, name: String, argv: Vec<String>, serves: Vec<String>) -> PyResult<Self> {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            node: NodeArgs,
        }
        let cli = Cli::try_parse_from(std::iter::once(name.clone()).chain(argv))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        interfaces::node::init_logging();
        let component = cli.node.name.clone().unwrap_or(name);
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .thread_name(format!("{component}-rt"))
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("cannot start the runtime: {e}")))?;
        let clock = cli.node.clock;
        let options = BusOptions {
            announce: true,
            ready_after_services: serves,
            clock: match clock {
                ClockSource::System => Clock::system(),
                ClockSource::Bus => Clock::virtual_unset(),
            },
        };
        let connect = cli.node.connect.clone();
        let bus = py
            .detach(|| rt.block_on(Bus::open_with(&connect, &component, options)))
            .map_err(bus_error)?;
        let (events_tx, events) = flume::bounded(64);
        let stopping = Arc::new(AtomicBool::new(false));
        let node = Node {
            bus: bus.clone(),
            events_tx: events_tx.clone(),
            events,
            stopping: stopping.clone(),
            callbacks: Default::default(),
            next_id: Default::default(),
            tasks: Default::default(),
            keep: Default::default(),
            rt,
        };
        let _guard = node.rt.enter();
        if clock == ClockSource::Bus {
            let follower = py
                .detach(|| node.rt.block_on(bus.follow_clock()))
                .map_err(bus_error)?;
            node.keep
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(Box::new(follower));
        }
        node.keep_task(tokio::spawn(interfaces::node::publish_diagnostics(
            bus.clone(),
        )));
        node.keep_task(tokio::spawn(async move {
            if let Ok(mut term) =
                tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            {
                term.recv().await;
                tracing::info!("SIGTERM: stopping");
                stopping.store(true, Ordering::Relaxed);
                let _ = events_tx.send_async(Event::Shutdown).await;
            }
        }));
        tracing::info!(
            namespace = bus.namespace(),
            "{} joined the bus",
            bus.component()
        );
        Ok(node)
    }

    /// The component's name on the bus.
    #[getter]
    fn name(&self) -> &str {
        self.bus.component()
    }

    #[getter]
    fn namespace(&self) -> &str {
        self.bus.namespace()
    }

    /// The node's time (ns since the epoch): the system's, or the bus clock under `--clock bus`.
    fn now_ns(&self) -> i64 {
        self.bus.clock().now_ns()
    }

    /// Add `n` to counter `name` of this component's `diagnostics`.
    #[pyo3(signature = (name, n=1))]
    fn count(&self, name: &str, n: u64) {
        self.bus
            .counters()
            .counter(name)
            .fetch_add(n, Ordering::Relaxed);
    }

    /// The value of counter `name` (0 if never counted).
    fn counter(&self, name: &str) -> u64 {
        self.bus.counters().counter(name).load(Ordering::Relaxed)
    }

    /// A publisher of `type_name` messages on `topic`.
    fn publisher(&self, py: Python<'_>, topic: String, type_name: &str) -> PyResult<PyPublisher> {
        let ops = types::ops(type_name)?;
        let bus = self.bus.clone();
        let t = topic.clone();
        let inner = py
            .detach(|| self.rt.block_on((ops.publisher)(bus, t)))
            .map_err(bus_error)?;
        Ok(PyPublisher {
            inner,
            rt: self.rt.handle().clone(),
            topic,
        })
    }

    /// Call `callback(msg)` (with `with_seq`, `callback(msg, seq)`) on the spinning thread for
    /// every `type_name` message on `topic`. At most `queue` messages wait for the callback; past
    /// that the oldest is dropped and counted (`queue_dropped/<topic>`). Returns the id.
    #[pyo3(signature = (topic, type_name, callback, queue=256, with_seq=false))]
    fn subscribe(
        &self,
        py: Python<'_>,
        topic: String,
        type_name: &str,
        callback: Py<PyAny>,
        queue: usize,
        with_seq: bool,
    ) -> PyResult<usize> {
        let ops = types::ops(type_name)?;
        let id = self.id();
        self.callbacks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id, callback);
        let info = Arc::new(SubscriptionInfo {
            topic,
            queue,
            id,
            with_seq,
        });
        let bus = self.bus.clone();
        let tx = self.events_tx.clone();
        let task = py
            .detach(|| {
                let _g = self.rt.enter();
                self.rt.block_on((ops.subscribe)(bus, info, tx))
            })
            .map_err(bus_error)?;
        self.keep_task(task);
        Ok(id)
    }

    /// Serve `service`: `handler(request)` runs on the spinning thread and returns the reply (a
    /// `ServiceError` it raises is the caller's typed error; any other exception an internal
    /// error, logged and counted).
    fn serve(
        &self,
        py: Python<'_>,
        service: String,
        request_type: &str,
        reply_type: &str,
        handler: Py<PyAny>,
    ) -> PyResult<usize> {
        let info = Arc::new(ServiceInfo {
            name: service.clone(),
            id: self.id(),
            request: types::ops(request_type)?,
            reply: types::ops(reply_type)?,
        });
        self.callbacks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(info.id, handler);
        let tx = self.events_tx.clone();
        let id = info.id;
        let handle = py
            .detach(|| {
                let _g = self.rt.enter();
                self.rt.block_on(self.bus.raw_serve(
                    &service,
                    request_type,
                    reply_type,
                    move |payload| {
                        let tx = tx.clone();
                        let service = info.clone();
                        async move {
                            let (reply, rx) = tokio::sync::oneshot::channel();
                            let event = Event::Request {
                                service,
                                payload,
                                reply,
                            };
                            if tx.send_async(event).await.is_err() {
                                return interfaces::raw::encode_error_reply(ServiceError::new(
                                    interfaces::bus::ErrorCode::Internal,
                                    "the component is stopping",
                                ));
                            }
                            rx.await.unwrap_or_else(|_| {
                                interfaces::raw::encode_error_reply(ServiceError::new(
                                    interfaces::bus::ErrorCode::Internal,
                                    "the component stopped before it answered",
                                ))
                            })
                        }
                    },
                ))
            })
            .map_err(bus_error)?;
        self.keep
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(Box::new(handle));
        Ok(id)
    }

    /// Call `service` with `request` (plain values of `request_type`) and return the reply as
    /// `reply_type`'s class. Raises `RemoteError(code, message)` for the server's typed error,
    /// `NoServerError` when nobody serves it, `TimeoutError` after `timeout_s`.
    #[pyo3(signature = (service, request_type, request, reply_type, timeout_s=2.0))]
    fn call(
        &self,
        py: Python<'_>,
        service: &str,
        request_type: &str,
        request: &Bound<'_, PyAny>,
        reply_type: &str,
        timeout_s: f64,
    ) -> PyResult<Py<PyAny>> {
        let req = types::ops(request_type)?;
        let rep = types::ops(reply_type)?;
        let payload = (req.encode)(request)?;
        let timeout = Duration::try_from_secs_f64(timeout_s)
            .map_err(|_| PyValueError::new_err(format!("timeout_s {timeout_s} is no duration")))?;
        let result = py.detach(|| {
            self.rt
                .block_on(self.bus.raw_call(service, request_type, payload, timeout))
        });
        match result {
            Ok(interfaces::raw::RawReply::Ok(wire)) => (rep.decode_reply)(py, wire),
            Ok(interfaces::raw::RawReply::Err(e)) => Err(service_error(&e)),
            Err(CallError::NoServer(s)) => Err(NoServerError::new_err(format!(
                "no component serves {s} in this namespace"
            ))),
            Err(CallError::Timeout { service, timeout }) => Err(PyTimeoutError::new_err(format!(
                "{service} did not answer within {timeout:?}"
            ))),
            Err(e) => Err(PyRuntimeError::new_err(e.to_string())),
        }
    }

    /// Call `callback()` on the spinning thread every `period_s` of the node's clock.
    fn timer(&self, period_s: f64, callback: Py<PyAny>) -> PyResult<usize> {
        let period = Duration::try_from_secs_f64(period_s)
            .ok()
            .filter(|d| !d.is_zero())
            .ok_or_else(|| PyValueError::new_err(format!("period_s {period_s} is no period")))?;
        let id = self.id();
        self.callbacks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id, callback);
        let tx = self.events_tx.clone();
        let clock = self.bus.clock().clone();
        let _g = self.rt.enter();
        self.keep_task(tokio::spawn(async move {
            let mut tick = clock.interval(period);
            tick.tick().await;
            loop {
                tick.tick().await;
                if tx.send_async(Event::Timer(id)).await.is_err() {
                    return;
                }
            }
        }));
        Ok(id)
    }

    /// Whether the component was asked to stop (SIGTERM, or `stop()`).
    fn stopping(&self) -> bool {
        self.stopping.load(Ordering::Relaxed)
    }

    /// Ask the component to stop: `spin` returns.
    fn stop(&self) {
        self.stopping.store(true, Ordering::Relaxed);
        let _ = self.events_tx.try_send(Event::Shutdown);
    }

    /// Run callbacks until the component is asked to stop, or for at most `timeout_s`. Returns
    /// the next thing to do: `None` when a callback ran or time ran out, else a tuple
    /// (`"error"`, kind, name, exception) for the package to log and count, or `("stop",)`.
    /// Ctrl-C raises `KeyboardInterrupt` here.
    #[pyo3(signature = (timeout_s=None))]
    #[expect(
        clippy::disallowed_methods,
        reason = "the caller's own wait, on the wall as Python's waits are (the node's clock may be a replay's)"
    )]
    fn spin_once(&self, py: Python<'_>, timeout_s: Option<f64>) -> PyResult<Option<Py<PyAny>>> {
        if self.stopping() {
            return Ok(Some(("stop",).into_pyobject(py)?.into_any().unbind()));
        }
        let deadline =
            timeout_s.map(|s| std::time::Instant::now() + Duration::from_secs_f64(s.max(0.0)));
        let event = loop {
            let slice = match deadline {
                Some(d) => d
                    .saturating_duration_since(std::time::Instant::now())
                    .min(Duration::from_millis(100)),
                None => Duration::from_millis(100),
            };
            match py.detach(|| self.events.recv_timeout(slice)) {
                Ok(e) => break e,
                Err(flume::RecvTimeoutError::Timeout) => {
                    py.check_signals()?;
                    if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                        return Ok(None);
                    }
                }
                Err(flume::RecvTimeoutError::Disconnected) => {
                    return Ok(Some(("stop",).into_pyobject(py)?.into_any().unbind()));
                }
            }
        };
        match event {
            Event::Shutdown => Ok(Some(("stop",).into_pyobject(py)?.into_any().unbind())),
            Event::Message(info, deliver, _turn) => {
                let Some(cb) = self.callback(py, info.id) else {
                    return Ok(None);
                };
                let outcome = deliver(py).and_then(|(msg, seq)| {
                    if info.with_seq {
                        cb.call1(py, (msg, seq))
                    } else {
                        cb.call1(py, (msg,))
                    }
                });
                Ok(outcome
                    .err()
                    .map(|e| error_tuple(py, "subscription", &info.topic, e))
                    .transpose()?)
            }
            Event::Timer(id) => {
                let Some(cb) = self.callback(py, id) else {
                    return Ok(None);
                };
                Ok(cb
                    .call0(py)
                    .err()
                    .map(|e| error_tuple(py, "timer", "timer", e))
                    .transpose()?)
            }
            Event::Request {
                service,
                payload,
                reply,
            } => {
                let Some(cb) = self.callback(py, service.id) else {
                    return Ok(None);
                };
                let outcome = (service.request.decode)(py, &payload)
                    .map_err(|e| (interfaces::bus::ErrorCode::BadRequest, e))
                    .and_then(|req| {
                        cb.call1(py, (req,))
                            .map_err(|e| (interfaces::bus::ErrorCode::Internal, e))
                    })
                    .and_then(|rep| {
                        (service.reply.encode_reply)(rep.bind(py))
                            .map_err(|e| (interfaces::bus::ErrorCode::Internal, e))
                    });
                match outcome {
                    Ok(bytes) => {
                        let _ = reply.send(bytes);
                        Ok(None)
                    }
                    Err((code, e)) => {
                        // A typed refusal raised by the handler goes back as it is.
                        let remote = e.is_instance_of::<RemoteError>(py);
                        let (code, message) = if remote {
                            let args = e.value(py).getattr("args")?;
                            let code: String = args.get_item(0)?.extract()?;
                            let message: String = args.get_item(1)?.extract()?;
                            (
                                error_code(&code).unwrap_or(interfaces::bus::ErrorCode::Internal),
                                message,
                            )
                        } else {
                            (code, e.to_string())
                        };
                        let _ = reply.send(interfaces::raw::encode_error_reply(ServiceError::new(
                            code, message,
                        )));
                        if remote {
                            Ok(None)
                        } else {
                            Ok(Some(error_tuple(py, "service", &service.name, e)?))
                        }
                    }
                }
            }
        }
    }
}

fn error_code(name: &str) -> Option<interfaces::bus::ErrorCode> {
    use interfaces::bus::ErrorCode::*;
    Some(match name {
        "BadRequest" => BadRequest,
        "NotFound" => NotFound,
        "Refused" => Refused,
        "Internal" => Internal,
        _ => return None,
    })
}

fn error_tuple(py: Python<'_>, kind: &str, name: &str, e: PyErr) -> PyResult<Py<PyAny>> {
    Ok(("error", kind, name, e.into_value(py))
        .into_pyobject(py)?
        .into_any()
        .unbind())
}

/// Encode `msg` (plain values) as a CDR payload of `type_name`: the bytes a Rust publisher sends.
#[pyfunction]
fn encode<'py>(
    py: Python<'py>,
    type_name: &str,
    msg: &Bound<'_, PyAny>,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = (types::ops(type_name)?.encode)(msg)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Decode a CDR payload of `type_name` into its class of `robocog.msg`.
#[pyfunction]
fn decode(py: Python<'_>, type_name: &str, payload: &[u8]) -> PyResult<Py<PyAny>> {
    (types::ops(type_name)?.decode)(py, payload)
}

/// Register the generated classes (`robocog.msg.CLASSES`) the decoder builds.
#[pyfunction]
fn set_classes(classes: Bound<'_, PyDict>) {
    let _ = types::CLASSES.set(classes.unbind());
}

/// Every message type name of this build.
#[pyfunction]
fn type_names() -> Vec<&'static str> {
    interfaces::msg::REGISTRY.iter().map(|e| e.name).collect()
}

/// The help of the flags every component accepts (`Node(argv=...)`).
#[pyfunction]
fn node_flags_help() -> String {
    use clap::CommandFactory;
    #[derive(clap::Parser)]
    #[command(name = "component")]
    struct Cli {
        #[command(flatten)]
        node: NodeArgs,
    }
    let mut cmd = Cli::command();
    cmd.render_help().to_string()
}

#[pymodule]
fn _robocog(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Node>()?;
    m.add_class::<PyPublisher>()?;
    m.add_class::<SampleBuffer>()?;
    m.add("RemoteError", m.py().get_type::<RemoteError>())?;
    m.add("NoServerError", m.py().get_type::<NoServerError>())?;
    m.add_function(wrap_pyfunction!(encode, m)?)?;
    m.add_function(wrap_pyfunction!(decode, m)?)?;
    m.add_function(wrap_pyfunction!(set_classes, m)?)?;
    m.add_function(wrap_pyfunction!(type_names, m)?)?;
    m.add_function(wrap_pyfunction!(node_flags_help, m)?)?;
    Ok(())
}
