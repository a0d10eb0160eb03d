//! A long-lived worker thread behind shared state, for work that must not
//! run on the UI thread (the render, the error readout). The UI writes a
//! request into the state and wakes the worker; the worker takes it, works,
//! writes the result back, wakes any waiter and asks egui for a repaint.
//! Dropping the handle tells the worker to stop and joins it.

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The state, its condition variable and the context to repaint.
pub struct Shared<S> {
    state: Mutex<S>,
    wake: Condvar,
    repaint: egui::Context,
}

impl<S> Shared<S> {
    pub fn lock(&self) -> MutexGuard<'_, S> {
        // A panic while locked leaves plain data behind: keep going.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Blocks until `done` holds; false on timeout. For tests and scripts,
    /// never called from the UI.
    pub fn wait_until(&self, timeout: Duration, done: impl Fn(&S) -> bool) -> bool {
        let deadline = Instant::now() + timeout;
        let mut s = self.lock();
        while !done(&s) {
            let now = Instant::now();
            if now >= deadline {
                return false;
            }
            s = self
                .wake
                .wait_timeout(s, deadline - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        true
    }

    /// Blocks while `hold` holds, looking again at each notify (the worker
    /// pausing part-way through its work).
    pub fn wait_while(&self, hold: impl Fn(&S) -> bool) {
        let mut s = self.lock();
        while hold(&s) {
            s = self.wake.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// The worker's next piece of work: `take` removes it from the state
    /// (and marks it started); waits while there is none. `None` once the
    /// worker is told to stop.
    pub fn next<T>(&self, mut take: impl FnMut(&mut S) -> Option<T>) -> Option<T>
    where
        S: Stop,
    {
        let mut s = self.lock();
        loop {
            if s.stopped() {
                return None;
            }
            if let Some(work) = take(&mut s) {
                return Some(work);
            }
            s = self.wake.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Wakes the worker and any waiter.
    pub fn notify(&self) {
        self.wake.notify_all();
    }

    /// Asks the UI for a frame (something new to show).
    pub fn repaint(&self) {
        self.repaint.request_repaint();
    }

    /// Wakes everyone and asks the UI for a frame: a result is ready.
    pub fn announce(&self) {
        self.notify();
        self.repaint();
    }
}

/// State that can tell its worker to stop.
pub trait Stop {
    /// Makes the worker return at its next look at the state (and cancels
    /// what it runs, if it can).
    fn stop(&mut self);
    /// Whether [`stop`](Self::stop) was called.
    fn stopped(&self) -> bool;
}

/// Handle to the worker thread.
pub struct Worker<S: Stop> {
    shared: Arc<Shared<S>>,
    thread: Option<JoinHandle<()>>,
}

impl<S: Stop + Send + 'static> Worker<S> {
    /// Starts thread `name` running `run` over the shared `state`.
    pub fn spawn(
        name: &str,
        state: S,
        repaint: egui::Context,
        run: impl FnOnce(&Shared<S>) + Send + 'static,
    ) -> Worker<S> {
        let shared = Arc::new(Shared {
            state: Mutex::new(state),
            wake: Condvar::new(),
            repaint,
        });
        let worker = shared.clone();
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || run(&worker))
            .unwrap_or_else(|e| panic!("spawn the {name} thread: {e}"));
        Worker {
            shared,
            thread: Some(thread),
        }
    }

    pub fn shared(&self) -> &Arc<Shared<S>> {
        &self.shared
    }
}

impl<S: Stop> Drop for Worker<S> {
    fn drop(&mut self) {
        self.shared.lock().stop();
        self.shared.notify();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
