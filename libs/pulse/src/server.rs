//! Asking the server things over a short-lived connection: its devices, its modules, loading and
//! unloading one.

use crate::{Device, Devices, Error, LIST_TIMEOUT, describe, server_label};
use libpulse_binding as pa;
use pa::callbacks::ListResult;
use pa::context::{Context, FlagSet as ContextFlags, State as ContextState};
use pa::mainloop::standard::{IterateResult, Mainloop};
use pa::operation::State as OperationState;
use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

/// A connection to the server for asking it things (its devices, its modules), every wait
/// bounded by [`LIST_TIMEOUT`] from the moment it was made.
struct Session {
    mainloop: Mainloop,
    context: Context,
    server: Option<String>,
    deadline: Instant,
}

impl Session {
    fn connect(server: Option<&str>) -> Result<Self, Error> {
        let no_server = |reason: String| Error::NoServer {
            server: server_label(server),
            reason,
        };
        let mainloop =
            Mainloop::new().ok_or_else(|| no_server("libpulse has no main loop".into()))?;
        let mut context = Context::new(&mainloop, "robocog")
            .ok_or_else(|| no_server("libpulse has no context".into()))?;
        context
            .connect(server, ContextFlags::NOAUTOSPAWN, None)
            .map_err(|e| no_server(describe(e)))?;
        #[expect(
            clippy::disallowed_methods,
            reason = "a transport time-out: how long a blocking caller waits for the real sound server to answer"
        )]
        let mut session = Session {
            mainloop,
            context,
            server: server.map(str::to_string),
            deadline: Instant::now() + LIST_TIMEOUT,
        };
        loop {
            match session.context.get_state() {
                ContextState::Ready => return Ok(session),
                ContextState::Failed | ContextState::Terminated => {
                    let reason = describe(session.context.errno());
                    return Err(session.no_server(reason));
                }
                _ => session.step()?,
            }
        }
    }

    fn no_server(&self, reason: String) -> Error {
        Error::NoServer {
            server: server_label(self.server.as_deref()),
            reason,
        }
    }

    /// Run the main loop once (or sleep briefly when it had nothing to do).
    #[expect(
        clippy::disallowed_methods,
        reason = "polls libpulse's main loop on the caller's blocking thread against the real sound server's time-out"
    )]
    fn step(&mut self) -> Result<(), Error> {
        if Instant::now() > self.deadline {
            return Err(self.no_server(format!("no answer within {} s", LIST_TIMEOUT.as_secs())));
        }
        match self.mainloop.iterate(false) {
            IterateResult::Success(0) => std::thread::sleep(Duration::from_millis(2)),
            IterateResult::Success(_) => {}
            IterateResult::Quit(_) => return Err(self.no_server("the main loop quit".into())),
            IterateResult::Err(e) => return Err(self.no_server(describe(e))),
        }
        Ok(())
    }

    /// Wait until none of `states` says running.
    fn wait(&mut self, states: impl Fn() -> bool) -> Result<(), Error> {
        while states() {
            self.step()?;
        }
        Ok(())
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.context.disconnect();
    }
}

/// The devices of the server at `server` (`None`: the usual address), waiting at most
/// [`LIST_TIMEOUT`] for it.
pub fn devices(server: Option<&str>) -> Result<Devices, Error> {
    let mut session = Session::connect(server)?;
    let found = Rc::new(RefCell::new(Devices::default()));
    let introspect = session.context.introspect();
    let f = Rc::clone(&found);
    let op_server = introspect.get_server_info(move |info| {
        let mut d = f.borrow_mut();
        d.server = format!(
            "{} {}",
            info.server_name.as_deref().unwrap_or("?"),
            info.server_version.as_deref().unwrap_or("?")
        );
        d.default_source = info
            .default_source_name
            .as_deref()
            .unwrap_or("")
            .to_string();
        d.default_sink = info.default_sink_name.as_deref().unwrap_or("").to_string();
    });
    let f = Rc::clone(&found);
    let op_sources = introspect.get_source_info_list(move |r| {
        if let ListResult::Item(s) = r {
            f.borrow_mut().sources.push(Device {
                name: s.name.as_deref().unwrap_or("").to_string(),
                description: s.description.as_deref().unwrap_or("").to_string(),
                rate_hz: s.sample_spec.rate,
                channels: s.sample_spec.channels,
                channel_map: s.channel_map.print(),
                monitor: s.monitor_of_sink.is_some(),
            });
        }
    });
    let f = Rc::clone(&found);
    let op_sinks = introspect.get_sink_info_list(move |r| {
        if let ListResult::Item(s) = r {
            f.borrow_mut().sinks.push(Device {
                name: s.name.as_deref().unwrap_or("").to_string(),
                description: s.description.as_deref().unwrap_or("").to_string(),
                rate_hz: s.sample_spec.rate,
                channels: s.sample_spec.channels,
                channel_map: s.channel_map.print(),
                monitor: false,
            });
        }
    });
    session.wait(|| {
        [
            op_server.get_state(),
            op_sources.get_state(),
            op_sinks.get_state(),
        ]
        .contains(&OperationState::Running)
    })?;
    let devices = found.borrow().clone();
    Ok(devices)
}

/// A module loaded in the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Module {
    pub index: u32,
    pub name: String,
    pub argument: String,
}

/// The modules loaded in the server at `server`.
pub fn modules(server: Option<&str>) -> Result<Vec<Module>, Error> {
    let mut session = Session::connect(server)?;
    let found = Rc::new(RefCell::new(Vec::new()));
    let f = Rc::clone(&found);
    let op = session.context.introspect().get_module_info_list(move |r| {
        if let ListResult::Item(m) = r {
            f.borrow_mut().push(Module {
                index: m.index,
                name: m.name.as_deref().unwrap_or("").to_string(),
                argument: m.argument.as_deref().unwrap_or("").to_string(),
            });
        }
    });
    session.wait(|| op.get_state() == OperationState::Running)?;
    let modules = found.borrow().clone();
    Ok(modules)
}

/// Load the module `name` with `argument` (`key=value` pairs separated by spaces) into the
/// server; its index. A module the server refuses (a bad argument, a master device it does not
/// have) is an [`Error::Invalid`] (the server's log says why).
pub fn load_module(server: Option<&str>, name: &str, argument: &str) -> Result<u32, Error> {
    if name.contains('\0') || argument.contains('\0') {
        return Err(Error::Invalid {
            what: format!("module {name:?}"),
            reason: "a NUL byte in its name or argument".into(),
        });
    }
    let mut session = Session::connect(server)?;
    let index = Rc::new(RefCell::new(None));
    let i = Rc::clone(&index);
    let op = session
        .context
        .introspect()
        .load_module(name, argument, move |n| *i.borrow_mut() = Some(n));
    session.wait(|| op.get_state() == OperationState::Running)?;
    let loaded = *index.borrow();
    match loaded {
        Some(n) if n != u32::MAX => Ok(n),
        _ => Err(Error::Invalid {
            what: format!("module {name} ({argument})"),
            reason: format!(
                "the sound server refused it: {}",
                describe(session.context.errno())
            ),
        }),
    }
}

/// Unload the module `index` from the server (one already gone is not an error).
pub fn unload_module(server: Option<&str>, index: u32) -> Result<(), Error> {
    let mut session = Session::connect(server)?;
    let op = session.context.introspect().unload_module(index, |_| {});
    session.wait(|| op.get_state() == OperationState::Running)
}
