//! Shutdown signalling, mini-redis style: one `watch` channel tells every task
//! to stop, and a "drained" `mpsc` channel, whose senders every task holds until
//! it has flushed its output, tells the main task when everything is done
//! (`recv()` returns `None` once the last [`DrainGuard`] is dropped).
//!
//! Blocking threads (the numeric pipeline, the simulated bench, the file
//! replays) poll [`Shutdown::is_requested`] between blocks; async tasks
//! `select!` on [`Shutdown::requested`].

use tokio::sync::{mpsc, watch};

/// The sending side: request a shutdown (SIGINT/SIGTERM, end of the run).
#[derive(Debug, Clone)]
pub struct ShutdownTrigger {
    tx: watch::Sender<bool>,
}

/// A task's view of the shutdown signal.
#[derive(Debug, Clone)]
pub struct Shutdown {
    rx: watch::Receiver<bool>,
}

/// A new trigger and its first receiver.
pub fn channel() -> (ShutdownTrigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (ShutdownTrigger { tx }, Shutdown { rx })
}

impl ShutdownTrigger {
    /// Ask every task to stop (idempotent).
    pub fn trigger(&self) {
        self.tx.send_replace(true);
    }

    /// Whether a shutdown was requested.
    pub fn is_triggered(&self) -> bool {
        *self.tx.borrow()
    }

    /// Another receiver.
    pub fn subscribe(&self) -> Shutdown {
        Shutdown {
            rx: self.tx.subscribe(),
        }
    }
}

impl Shutdown {
    /// Resolves once a shutdown is requested (or the trigger is gone).
    pub async fn requested(&mut self) {
        let _ = self.rx.wait_for(|stop| *stop).await;
    }

    /// Non-blocking check, for blocking threads.
    pub fn is_requested(&self) -> bool {
        *self.rx.borrow() || self.rx.has_changed().is_err()
    }

    /// The underlying receiver (e.g. for [`crate::daemon::http::bind`]).
    pub fn watch(&self) -> watch::Receiver<bool> {
        self.rx.clone()
    }
}

/// Held by a task until it has drained its output.
#[derive(Debug, Clone)]
pub struct DrainGuard {
    _tx: mpsc::Sender<()>,
}

/// Waits until every [`DrainGuard`] is dropped.
#[derive(Debug)]
pub struct Drained {
    rx: mpsc::Receiver<()>,
}

/// A drain guard (clone it for every task) and its waiter.
pub fn drain_channel() -> (DrainGuard, Drained) {
    let (tx, rx) = mpsc::channel(1);
    (DrainGuard { _tx: tx }, Drained { rx })
}

impl Drained {
    /// Resolves once every guard is dropped.
    pub async fn wait(mut self) {
        // Nothing is ever sent: recv() returns None when the last sender goes.
        let _ = self.rx.recv().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn trigger_reaches_every_receiver_and_drain_waits_for_all_guards() {
        let (trigger, mut a) = channel();
        let b = trigger.subscribe();
        assert!(!a.is_requested() && !b.is_requested());
        let (guard, drained) = drain_channel();
        let g2 = guard.clone();
        let task = tokio::spawn(async move {
            a.requested().await;
            drop(g2);
        });
        drop(guard);
        trigger.trigger();
        assert!(b.is_requested() && trigger.is_triggered());
        tokio::time::timeout(std::time::Duration::from_secs(5), drained.wait())
            .await
            .expect("drain must complete once every guard is dropped");
        task.await.unwrap();
    }

    #[test]
    fn a_dropped_trigger_counts_as_requested() {
        let (trigger, rx) = channel();
        drop(trigger);
        assert!(rx.is_requested());
    }
}
