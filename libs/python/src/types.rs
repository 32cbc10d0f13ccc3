//! What Python can do with each message type of the registry, by its name: the Rust type's own
//! codec, publisher and subscriber, reached through one table of functions made for every type
//! (`interfaces::msg::visit_types`). Nothing here knows a type's fields.

use crate::topy::{Lender, ToPy, to_py};
use crate::{Event, SubscriptionInfo};
use interfaces::bus::{Bus, BusError, Publisher};
use interfaces::codec;
use interfaces::msg::vision::RgbdFrame;
use interfaces::msg::{Borrowable, Message, TypeVisitor};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, OnceLock};

type BoxFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;

/// A message made into Python objects on the thread that runs the callbacks, with its sequence
/// number (from the sample's attachment; the wire form of a header has none).
pub type Delivery = Box<dyn FnOnce(Python<'_>) -> PyResult<(Py<PyAny>, u64)> + Send>;

/// A publisher of a type known by name.
pub trait AnyPublisher: Send + Sync {
    /// Convert `msg`, stamp it (sequence, and time when its stamp is 0) and publish it.
    fn publish(
        &self,
        py: Python<'_>,
        msg: &Bound<'_, PyAny>,
        rt: &tokio::runtime::Handle,
    ) -> PyResult<()>;
}

impl<T: Message> AnyPublisher for Publisher<T> {
    fn publish(
        &self,
        py: Python<'_>,
        msg: &Bound<'_, PyAny>,
        rt: &tokio::runtime::Handle,
    ) -> PyResult<()> {
        let mut value: T = from_py(msg)?;
        py.detach(|| rt.block_on(Publisher::publish(self, &mut value)))
            .map_err(crate::bus_error)
    }
}

/// A publisher of a type whose byte blocks are read in place from Python's buffers
/// ([`crate::frompy::with_view`]): a frame's pixels go from the NumPy arrays straight into the
/// shared-memory sample, one copy.
struct ViewPublisher<T: Borrowable>(Publisher<T>);

impl<T: Borrowable> AnyPublisher for ViewPublisher<T> {
    fn publish(
        &self,
        py: Python<'_>,
        msg: &Bound<'_, PyAny>,
        rt: &tokio::runtime::Handle,
    ) -> PyResult<()> {
        crate::frompy::with_view::<T, _>(msg, |view| {
            py.detach(|| rt.block_on(self.0.publish_view(view)))
        })
        .map_err(|e| PyValueError::new_err(format!("this is not a {}: {e}", T::TYPE_NAME)))?
        .map_err(crate::bus_error)
    }
}

/// [`encode`] for a type whose byte blocks are read in place from Python's buffers.
fn encode_view<T: Borrowable>(msg: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    crate::frompy::with_view::<T, _>(msg, |view| codec::encode(&*view, T::TYPE_NAME))
        .map_err(|e| PyValueError::new_err(format!("this is not a {}: {e}", T::TYPE_NAME)))?
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

fn view_publisher<T: Borrowable>(
    bus: Bus,
    topic: String,
) -> BoxFuture<Result<Box<dyn AnyPublisher>, BusError>> {
    Box::pin(async move {
        let p = bus.publisher_named::<T>(&topic).await?;
        Ok(Box::new(ViewPublisher(p)) as Box<dyn AnyPublisher>)
    })
}

/// One message type's functions.
#[derive(Clone, Copy)]
pub struct Ops {
    pub encode: fn(&Bound<'_, PyAny>) -> PyResult<Vec<u8>>,
    pub decode: fn(Python<'_>, &[u8]) -> PyResult<Py<PyAny>>,
    /// A service's reply payload (the value, or the typed error raised as `ServiceError`).
    pub decode_reply: fn(Python<'_>, Vec<u8>) -> PyResult<Py<PyAny>>,
    pub encode_reply: fn(&Bound<'_, PyAny>) -> PyResult<Vec<u8>>,
    pub publisher: MakePublisher,
    pub subscribe: Subscribe,
}

/// Declares a publisher of one type on a topic.
pub type MakePublisher = fn(Bus, String) -> BoxFuture<Result<Box<dyn AnyPublisher>, BusError>>;

/// Subscribes to a topic of one type, handing each message to the callback thread; the task
/// that does it.
pub type Subscribe = fn(
    Bus,
    Arc<SubscriptionInfo>,
    flume::Sender<Event>,
) -> BoxFuture<Result<tokio::task::JoinHandle<()>, BusError>>;

/// The functions of type `name`, or the error Python sees.
pub fn ops(name: &str) -> PyResult<&'static Ops> {
    static TABLE: OnceLock<HashMap<&'static str, Ops>> = OnceLock::new();
    TABLE
        .get_or_init(|| {
            let mut t = Table(HashMap::new());
            interfaces::msg::visit_types(&mut t);
            // Frames are lent to Python, and read from Python's buffers, not copied.
            if let Some(o) = t.0.get_mut(RgbdFrame::TYPE_NAME) {
                o.subscribe = subscribe_borrowed::<RgbdFrame>;
                o.publisher = view_publisher::<RgbdFrame>;
                o.encode = encode_view::<RgbdFrame>;
            }
            t.0
        })
        .get(name)
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "unknown message type {name:?} (robocog.msg.TYPES lists this build's types)"
            ))
        })
}

struct Table(HashMap<&'static str, Ops>);

impl TypeVisitor for Table {
    fn visit<T: Message>(&mut self) {
        self.0.insert(
            T::TYPE_NAME,
            Ops {
                encode: encode::<T>,
                decode: decode::<T>,
                decode_reply: decode_reply::<T>,
                encode_reply: encode_reply::<T>,
                publisher: publisher::<T>,
                subscribe: subscribe_owned::<T>,
            },
        );
    }
}

/// The generated classes (`robocog.msg.CLASSES`), registered by the package at import.
pub static CLASSES: OnceLock<Py<PyDict>> = OnceLock::new();

fn cx<'a, 'py>(py: Python<'py>, classes: Option<&'a Bound<'py, PyDict>>) -> ToPy<'a, 'py> {
    ToPy {
        py,
        classes,
        lender: None,
    }
}

/// A Python message (a dataclass of `robocog.msg`, converted to plain values by the package, or
/// plain values) as `T`.
pub fn from_py<T: Message>(msg: &Bound<'_, PyAny>) -> PyResult<T> {
    crate::frompy::from_py::<T>(msg)
        .map_err(|e| PyValueError::new_err(format!("this is not a {}: {e}", T::TYPE_NAME)))
}

fn encode<T: Message>(msg: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    let value: T = from_py(msg)?;
    codec::encode(&value, T::TYPE_NAME).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn decode<T: Message>(py: Python<'_>, bytes: &[u8]) -> PyResult<Py<PyAny>> {
    let value: T = codec::decode(bytes, T::TYPE_NAME).map_err(crate::decode_error)?;
    let classes = CLASSES.get().map(|c| c.bind(py).clone());
    Ok(to_py(&value, cx(py, classes.as_ref()))?.unbind())
}

fn decode_reply<T: Message>(py: Python<'_>, wire: Vec<u8>) -> PyResult<Py<PyAny>> {
    let reply = interfaces::raw::decode_reply(wire).map_err(crate::decode_error)?;
    match reply.value::<T>() {
        Some(Ok(value)) => {
            let classes = CLASSES.get().map(|c| c.bind(py).clone());
            Ok(to_py(&value, cx(py, classes.as_ref()))?.unbind())
        }
        Some(Err(e)) => Err(crate::decode_error(e)),
        None => match reply {
            interfaces::raw::RawReply::Err(e) => Err(crate::service_error(&e)),
            interfaces::raw::RawReply::Ok(_) => Err(PyValueError::new_err("an empty reply")),
        },
    }
}

fn encode_reply<T: Message>(msg: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    let value: T = from_py(msg)?;
    interfaces::raw::encode_reply(Ok(value)).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn publisher<T: Message>(
    bus: Bus,
    topic: String,
) -> BoxFuture<Result<Box<dyn AnyPublisher>, BusError>> {
    Box::pin(async move {
        let p = bus.publisher_named::<T>(&topic).await?;
        Ok(Box::new(p) as Box<dyn AnyPublisher>)
    })
}

/// Subscribe to a topic of `T`, each message decoded (and counted, or dropped and counted) by
/// the typed subscriber, handed to the callback thread as its Python objects.
fn subscribe_owned<T: Message>(
    bus: Bus,
    info: Arc<SubscriptionInfo>,
    events: flume::Sender<Event>,
) -> BoxFuture<Result<tokio::task::JoinHandle<()>, BusError>> {
    Box::pin(async move {
        let sub = bus.subscriber_named::<T>(&info.topic, info.queue).await?;
        let turn = Arc::new(tokio::sync::Semaphore::new(1));
        Ok(tokio::spawn(async move {
            // One message of the subscription at a time waits for the callback thread; the
            // others wait in the subscriber's own queue (bounded: the oldest dropped, counted).
            while let Ok(permit) = turn.clone().acquire_owned().await {
                let Ok(msg) = sub.recv().await else { return };
                let deliver: Delivery = Box::new(move |py| {
                    let classes = CLASSES.get().map(|c| c.bind(py).clone());
                    let seq = msg.header().seq;
                    Ok((to_py(&msg, cx(py, classes.as_ref()))?.unbind(), seq))
                });
                if events
                    .send_async(Event::Message(info.clone(), deliver, permit))
                    .await
                    .is_err()
                {
                    return;
                }
            }
        }))
    })
}

/// Subscribe to a topic of a type whose byte blocks are lent: each payload stays where zenoh
/// delivered it (a frame's shared-memory buffer) and its byte fields are `memoryview`s of it.
fn subscribe_borrowed<T: Borrowable>(
    bus: Bus,
    info: Arc<SubscriptionInfo>,
    events: flume::Sender<Event>,
) -> BoxFuture<Result<tokio::task::JoinHandle<()>, BusError>> {
    Box::pin(async move {
        let sub = bus.subscriber_named::<T>(&info.topic, info.queue).await?;
        let turn = Arc::new(tokio::sync::Semaphore::new(1));
        Ok(tokio::spawn(async move {
            while let Ok(permit) = turn.clone().acquire_owned().await {
                let Ok(received) = sub.recv_borrowed().await else {
                    return;
                };
                let deliver: Delivery = Box::new(move |py| {
                    let owner = Bound::new(
                        py,
                        crate::SampleBuffer {
                            payload: Box::new(received),
                        },
                    )?;
                    let bytes = owner.get().payload.bytes();
                    let mut view: T::View<'_> =
                        codec::decode_borrowed(bytes, T::TYPE_NAME).map_err(crate::decode_error)?;
                    let seq = owner.get().payload.seq();
                    T::view_header_mut(&mut view).seq = seq;
                    let classes = CLASSES.get().map(|c| c.bind(py).clone());
                    let owner_any = owner.as_any();
                    let cx = ToPy {
                        py,
                        classes: classes.as_ref(),
                        lender: Some(Lender {
                            bytes,
                            owner: owner_any,
                        }),
                    };
                    Ok((to_py(&view, cx)?.unbind(), seq))
                });
                if events
                    .send_async(Event::Message(info.clone(), deliver, permit))
                    .await
                    .is_err()
                {
                    return;
                }
            }
        }))
    })
}
