//! Subscriptions to the robot's streams: the camera's frames ([`crate::Camera::subscribe`])
//! and the firmware's telemetry ([`crate::Robot::subscribe_telemetry`]).
//!
//! A subscription is a bounded queue that the robot fills as its time passes: whoever lets
//! time pass (a wait, a motion's wait, a capture) delivers what became due to every live
//! subscription, oldest first. A full queue drops its oldest item and counts it
//! ([`Subscription::dropped`]); the robot never waits for a reader. A subscription its holder
//! drops is forgotten at the next delivery, and while no subscription to frames is alive the
//! camera takes no picture for one.

use std::collections::VecDeque;
use std::sync::{Arc, Weak};

use parking_lot::{Condvar, Mutex};

use crate::error::{Error, Result};

/// The longest queue a subscription may ask for, items.
pub const MAX_QUEUE: usize = 100_000;

/// One subscriber's queue.
#[derive(Debug)]
struct Queue<T> {
    items: VecDeque<T>,
    capacity: usize,
    delivered: u64,
    dropped: u64,
    /// Rung at every delivery, when the holder asked ([`Subscription::ring`]).
    bell: Option<Arc<Bell>>,
    /// Whether the robot's time is virtual (it passes only when the robot is driven), so
    /// that a full queue may hold it ([`Subscription::pause_when_full`]).
    virtual_time: bool,
    /// Whether a full queue holds the robot's time until an item is taken.
    pause: bool,
}

/// Wakes whoever reads one or more subscriptions when any of them receives an item
/// ([`Subscription::ring`]), so that a reader on another thread (a recorder) waits without
/// polling.
#[derive(Debug, Default)]
pub struct Bell {
    rung: Mutex<bool>,
    cv: Condvar,
}

impl Bell {
    /// A bell not yet rung.
    pub fn new() -> Arc<Bell> {
        Arc::new(Bell::default())
    }

    /// Rings it: wakes a waiter, or the next wait returns at once.
    pub fn ring(&self) {
        *self.rung.lock() = true;
        self.cv.notify_all();
    }

    /// Waits until the bell rings or `timeout` passes (wall time); whether it rang. Each ring
    /// ends one wait.
    pub fn wait(&self, timeout: std::time::Duration) -> bool {
        let mut rung = self.rung.lock();
        if !*rung {
            let _ = self.cv.wait_for(&mut rung, timeout);
        }
        std::mem::take(&mut *rung)
    }
}

/// A subscription to one of the robot's streams: a queue of at most
/// [`Subscription::capacity`] items, filled as the robot's time passes. It may be moved to
/// another thread; dropping it unsubscribes.
pub struct Subscription<T> {
    queue: Arc<Mutex<Queue<T>>>,
    /// Signalled when items are taken (a publisher held by a full queue waits on it).
    room: Arc<Condvar>,
}

impl<T> Subscription<T> {
    /// The oldest item not yet taken, if any (never waits).
    pub fn try_next(&self) -> Option<T> {
        let item = self.queue.lock().items.pop_front();
        self.room.notify_all();
        item
    }

    /// Every item not yet taken, oldest first (never waits).
    pub fn drain(&self) -> Vec<T> {
        let items = self.queue.lock().items.drain(..).collect();
        self.room.notify_all();
        items
    }

    /// On a robot whose time is virtual (the in-process simulator: it passes only while the
    /// robot is driven), a full queue from now on holds the robot's time until an item is
    /// taken, instead of dropping the oldest: nothing is lost, and the simulation waits for
    /// a slow reader (a recorder on a slow disk). Dropping the subscription releases it.
    /// On a robot in real time, [`Error::Usage`]: its control loop waits for nobody.
    pub fn pause_when_full(&self) -> Result<()> {
        let mut q = self.queue.lock();
        if !q.virtual_time {
            return Err(Error::Usage(
                "a full queue can hold only a simulated robot's time; a real robot's \
                 subscription drops its oldest items"
                    .into(),
            ));
        }
        q.pause = true;
        Ok(())
    }

    /// Items waiting to be taken.
    pub fn len(&self) -> usize {
        self.queue.lock().items.len()
    }

    /// Whether no item waits.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The most items the queue holds.
    pub fn capacity(&self) -> usize {
        self.queue.lock().capacity
    }

    /// Items delivered since subscribing, taken or not (dropped ones included).
    pub fn delivered(&self) -> u64 {
        self.queue.lock().delivered
    }

    /// Rings `bell` at every item delivered from now on (one bell may serve several
    /// subscriptions).
    pub fn ring(&self, bell: Arc<Bell>) {
        self.queue.lock().bell = Some(bell);
    }

    /// Items dropped since subscribing because the queue was full (the oldest go first).
    pub fn dropped(&self) -> u64 {
        self.queue.lock().dropped
    }
}

impl<T> std::fmt::Debug for Subscription<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let q = self.queue.lock();
        f.debug_struct("Subscription")
            .field("waiting", &q.items.len())
            .field("capacity", &q.capacity)
            .field("delivered", &q.delivered)
            .field("dropped", &q.dropped)
            .finish()
    }
}

/// A subscription as its publisher holds it: its queue, and the condition a full pausing
/// queue waits on.
type Subscriber<T> = (Weak<Mutex<Queue<T>>>, Arc<Condvar>);

/// The robot's side of a stream: the live subscriptions' queues.
pub(crate) struct Publisher<T> {
    queues: Vec<Subscriber<T>>,
    /// Whether the robot's time is virtual ([`Subscription::pause_when_full`]).
    pub(crate) virtual_time: bool,
}

impl<T> Default for Publisher<T> {
    fn default() -> Self {
        Publisher {
            queues: Vec::new(),
            virtual_time: false,
        }
    }
}

impl<T: Clone> Publisher<T> {
    /// A new subscription of `capacity` items, in `[1, MAX_QUEUE]`, to the stream `what`.
    pub(crate) fn subscribe(&mut self, what: &str, capacity: usize) -> Result<Subscription<T>> {
        if !(1..=MAX_QUEUE).contains(&capacity) {
            return Err(Error::OutOfRange {
                what: format!("{what} subscription's queue length"),
                value: capacity as f64,
                min: 1.0,
                max: MAX_QUEUE as f64,
            });
        }
        let queue = Arc::new(Mutex::new(Queue {
            items: VecDeque::new(),
            capacity,
            delivered: 0,
            dropped: 0,
            bell: None,
            virtual_time: self.virtual_time,
            pause: false,
        }));
        let room = Arc::new(Condvar::new());
        self.queues.push((Arc::downgrade(&queue), room.clone()));
        Ok(Subscription { queue, room })
    }

    /// Whether any subscription is alive (forgetting those dropped).
    pub(crate) fn wanted(&mut self) -> bool {
        self.queues.retain(|(q, _)| q.strong_count() > 0);
        !self.queues.is_empty()
    }

    /// Delivers `item` to every live subscription.
    pub(crate) fn publish(&mut self, item: T) {
        self.queues.retain(|(weak, room)| {
            let Some(queue) = weak.upgrade() else {
                return false;
            };
            let mut q = queue.lock();
            // A pausing queue waits for room while its subscription lives (this `queue` is
            // the other strong reference); checked every 50 ms of wall time.
            while q.pause && q.items.len() == q.capacity && Arc::strong_count(&queue) > 1 {
                room.wait_for(&mut q, std::time::Duration::from_millis(50));
            }
            if q.items.len() == q.capacity {
                q.items.pop_front();
                q.dropped += 1;
            }
            q.items.push_back(item.clone());
            q.delivered += 1;
            if let Some(b) = &q.bell {
                b.ring();
            }
            true
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_queue_drops_its_oldest_and_a_dropped_subscription_is_forgotten() {
        let mut p = Publisher::default();
        assert!(!p.wanted());
        let a = p.subscribe("test", 2).unwrap();
        let b = p.subscribe("test", 10).unwrap();
        for i in 0..5 {
            p.publish(i);
        }
        assert_eq!(a.drain(), vec![3, 4]);
        assert_eq!((a.delivered(), a.dropped()), (5, 3));
        assert_eq!(b.try_next(), Some(0));
        assert_eq!((b.len(), b.dropped()), (4, 0));
        drop(a);
        p.publish(5);
        assert!(p.wanted());
        assert_eq!(p.queues.len(), 1);
        drop(b);
        assert!(!p.wanted());
        for bad in [0, MAX_QUEUE + 1, usize::MAX] {
            assert!(matches!(
                p.subscribe("test", bad),
                Err(Error::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn a_pausing_queue_holds_its_publisher_until_an_item_is_taken_and_only_in_virtual_time() {
        let mut real: Publisher<u32> = Publisher::default();
        let s = real.subscribe("test", 1).unwrap();
        assert!(matches!(s.pause_when_full(), Err(Error::Usage(_))));
        let mut p = Publisher {
            virtual_time: true,
            ..Publisher::default()
        };
        let s = p.subscribe("test", 2).unwrap();
        s.pause_when_full().unwrap();
        let bell = Bell::new();
        s.ring(bell.clone());
        let publisher = std::thread::spawn(move || {
            for i in 0..6 {
                p.publish(i);
            }
            p
        });
        let mut got = Vec::new();
        while got.len() < 6 {
            bell.wait(std::time::Duration::from_millis(100));
            got.extend(s.drain());
        }
        let mut p = publisher.join().unwrap();
        assert_eq!(got, (0..6).collect::<Vec<_>>());
        assert_eq!(s.dropped(), 0);
        // A subscription dropped while full releases its publisher.
        p.publish(6);
        p.publish(7);
        drop(s);
        p.publish(8);
        assert!(!p.wanted());
    }
}
