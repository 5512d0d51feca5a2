//! The recorder's queue: a std channel bounded in messages rather than entries.
//!
//! A sender takes one slot per message of the entry it queues, and the writer
//! thread gives the slots back as it takes each entry off the queue. So a group
//! of many messages is one hand-over (one wake of the writer thread), while the
//! queue never holds more than its capacity in messages, however they are
//! grouped. When the receiving end is dropped, blocked senders wake and their
//! entries are refused.

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

/// An entry of the queue, which counts its messages.
pub(super) trait Weighed {
    /// The slots the entry takes (0 for a command that carries no message).
    fn messages(&self) -> usize;
}

/// Why an entry was not queued.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Refused {
    /// Not enough free slots (`try_send` only).
    Full,
    /// The receiving end is gone.
    Stopped,
}

/// The sending end (cloneable).
pub(super) struct QueueSender<T> {
    tx: Sender<T>,
    slots: Arc<Slots>,
}

impl<T> Clone for QueueSender<T> {
    fn clone(&self) -> Self {
        QueueSender {
            tx: self.tx.clone(),
            slots: Arc::clone(&self.slots),
        }
    }
}

/// The receiving end. Dropping it wakes the senders blocked on a full queue.
pub(super) struct QueueReceiver<T> {
    // Field order matters: the channel is dropped before the slots are closed,
    // so a sender woken by the closing finds the channel disconnected.
    rx: Receiver<T>,
    slots: Closer,
}

/// A queue of at most `capacity` messages (at least one).
pub(super) fn queue<T: Weighed>(capacity: usize) -> (QueueSender<T>, QueueReceiver<T>) {
    let (tx, rx) = mpsc::channel();
    let slots = Arc::new(Slots {
        capacity: capacity.max(1),
        state: Mutex::new(State::default()),
        freed: Condvar::new(),
    });
    let closer = Closer(Arc::clone(&slots));
    (
        QueueSender { tx, slots },
        QueueReceiver { rx, slots: closer },
    )
}

impl<T: Weighed> QueueSender<T> {
    /// Queue `item`, blocking while its messages do not fit.
    pub(super) fn send(&self, item: T) -> Result<(), Refused> {
        let n = self.slots.clamp(item.messages());
        self.slots.take(n);
        self.tx.send(item).map_err(|_| Refused::Stopped)
    }

    /// Queue `item` if its messages fit now.
    pub(super) fn try_send(&self, item: T) -> Result<(), Refused> {
        let n = self.slots.clamp(item.messages());
        if !self.slots.try_take(n) {
            return Err(Refused::Full);
        }
        self.tx.send(item).map_err(|_| Refused::Stopped)
    }
}

impl<T: Weighed> QueueReceiver<T> {
    /// The next entry; `None` once every sender is gone and the queue is empty.
    pub(super) fn recv(&self) -> Option<T> {
        let item = self.rx.recv().ok()?;
        Some(self.taken(item))
    }

    /// The next entry, waiting at most `timeout`.
    pub(super) fn recv_timeout(&self, timeout: Duration) -> Result<T, RecvTimeoutError> {
        let item = self.rx.recv_timeout(timeout)?;
        Ok(self.taken(item))
    }

    fn taken(&self, item: T) -> T {
        let slots = &self.slots.0;
        slots.give_back(slots.clamp(item.messages()));
        item
    }
}

/// The message count shared by both ends.
struct Slots {
    capacity: usize,
    state: Mutex<State>,
    freed: Condvar,
}

#[derive(Default)]
struct State {
    /// Messages queued and not yet taken by the receiver.
    queued: usize,
    /// Senders waiting for slots.
    waiting: usize,
    /// The receiver is gone: nothing waits any more.
    closed: bool,
}

impl Slots {
    /// An entry larger than the whole queue takes all of it (it then waits
    /// for an empty queue rather than for ever).
    fn clamp(&self, n: usize) -> usize {
        n.min(self.capacity)
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // The state is three counters, consistent after every update: a
        // panic elsewhere while it was locked leaves nothing half-done.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn fits(&self, s: &State, n: usize) -> bool {
        s.queued + n <= self.capacity
    }

    /// Take `n` slots if they are free now (after closing: true, without
    /// counting, and the send then finds the channel disconnected).
    fn try_take(&self, n: usize) -> bool {
        let mut s = self.lock();
        if s.closed {
            return true;
        }
        if !self.fits(&s, n) {
            return false;
        }
        s.queued += n;
        true
    }

    /// Take `n` slots, waiting until they are free or the receiver is gone.
    fn take(&self, n: usize) {
        let mut s = self.lock();
        while !s.closed && !self.fits(&s, n) {
            s.waiting += 1;
            s = self.freed.wait(s).unwrap_or_else(PoisonError::into_inner);
            s.waiting -= 1;
        }
        if !s.closed {
            s.queued += n;
        }
    }

    fn give_back(&self, n: usize) {
        let mut s = self.lock();
        s.queued = s.queued.saturating_sub(n);
        if s.waiting > 0 {
            self.freed.notify_all();
        }
    }

    fn close(&self) {
        let mut s = self.lock();
        s.closed = true;
        self.freed.notify_all();
    }
}

/// Closes the slots when the receiver is dropped.
struct Closer(Arc<Slots>);

impl Drop for Closer {
    fn drop(&mut self) {
        self.0.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Group(usize);

    impl Weighed for Group {
        fn messages(&self) -> usize {
            self.0
        }
    }

    #[test]
    fn bounded_in_messages_not_entries() {
        let (tx, rx) = queue::<Group>(10);
        tx.try_send(Group(6)).unwrap();
        tx.try_send(Group(4)).unwrap();
        assert_eq!(tx.try_send(Group(1)), Err(Refused::Full));
        tx.try_send(Group(0)).unwrap(); // a command without messages
        assert_eq!(rx.recv().map(|g| g.0), Some(6));
        assert_eq!(tx.try_send(Group(7)), Err(Refused::Full));
        tx.try_send(Group(6)).unwrap();
    }

    #[test]
    fn oversized_entry_takes_the_whole_queue() {
        let (tx, rx) = queue::<Group>(4);
        tx.try_send(Group(9)).unwrap();
        assert_eq!(tx.try_send(Group(1)), Err(Refused::Full));
        rx.recv().unwrap();
        tx.try_send(Group(1)).unwrap();
    }

    #[test]
    fn blocked_sender_waits_for_slots_then_for_the_receiver() {
        let (tx, rx) = queue::<Group>(2);
        tx.send(Group(2)).unwrap();
        let blocked = tx.clone();
        let t = std::thread::spawn(move || blocked.send(Group(2)));
        assert_eq!(rx.recv().map(|g| g.0), Some(2));
        t.join().unwrap().unwrap();
        let blocked = tx.clone();
        let t = std::thread::spawn(move || blocked.send(Group(1)));
        drop(rx);
        assert_eq!(t.join().unwrap(), Err(Refused::Stopped));
        assert_eq!(tx.try_send(Group(1)), Err(Refused::Stopped));
    }
}
