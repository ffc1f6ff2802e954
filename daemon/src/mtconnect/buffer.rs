//! The observation buffer: a ring of the last `capacity` observations with sequence numbers
//! that increase by one without gaps, and the state of every data item before the ring's first
//! observation, so `/current?at=` can be answered for any sequence still in the ring.

use std::collections::VecDeque;

/// Condition level (Streams: `Normal`, `Warning`, `Fault`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Normal,
    Warning,
    Fault,
}

impl Level {
    pub fn element(self) -> &'static str {
        match self {
            Level::Normal => "Normal",
            Level::Warning => "Warning",
            Level::Fault => "Fault",
        }
    }
}

/// A condition observation: an alarm raised (Warning/Fault) or cleared (Normal).
#[derive(Clone, Debug, PartialEq)]
pub struct Cond {
    pub level: Level,
    /// The alarm's stable code (`following_error`); a Normal without code clears every alarm
    /// of the data item.
    pub native_code: Option<String>,
    /// `HIGH` or `LOW` (the standard's qualifier): which side of its range the value left.
    pub qualifier: Option<&'static str>,
    pub message: String,
}

/// The value of an observation.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Unavailable,
    Number(f64),
    Vector([f64; 3]),
    Text(String),
    /// Boxed: conditions are rare, and the ring holds `buffer_size` observations (56 bytes
    /// each with the box, 96 without).
    Condition(Box<Cond>),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Observation {
    pub sequence: u64,
    /// Wall-clock time, ns since the Unix epoch.
    pub time_ns: u64,
    /// Index into the model's data items.
    pub item: usize,
    pub value: Value,
}

/// What a data item shows in `/current`: its last observation, and for a condition the
/// alarms in force (each with its own observation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ItemState {
    pub last: Option<Observation>,
    pub active: Vec<Observation>,
}

impl ItemState {
    fn apply(&mut self, o: &Observation) {
        match &o.value {
            Value::Condition(c) if c.level != Level::Normal => {
                self.active
                    .retain(|a| cond_code(a) != c.native_code.as_deref());
                self.active.push(o.clone());
            }
            Value::Condition(c) if c.native_code.is_some() => {
                self.active
                    .retain(|a| cond_code(a) != c.native_code.as_deref());
            }
            _ => self.active.clear(),
        }
        self.last = Some(o.clone());
    }

    /// The observations `/current` shows: the active alarms, else the last observation.
    pub fn shown(&self) -> impl Iterator<Item = &Observation> {
        let active = !self.active.is_empty();
        self.active
            .iter()
            .chain(self.last.iter().filter(move |_| !active))
    }
}

fn cond_code(o: &Observation) -> Option<&str> {
    match &o.value {
        Value::Condition(c) => c.native_code.as_deref(),
        _ => None,
    }
}

/// Why a request's sequence numbers cannot be served (MTConnectError `OUT_OF_RANGE`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("'{param}' must be between {first} and {last}, it is {value}")]
pub struct OutOfRange {
    pub param: &'static str,
    pub value: u64,
    pub first: u64,
    pub last: u64,
}

/// The ring buffer of observations. It grows as observations come, up to `capacity` (a ring
/// of the default 131,072 holds 7 MiB once full; an agent that has seen few holds little).
#[derive(Clone, Debug)]
pub struct Buffer {
    ring: VecDeque<Observation>,
    capacity: usize,
    next: u64,
    /// Each item's state before the ring's first observation.
    base: Vec<ItemState>,
    latest: Vec<ItemState>,
}

impl Buffer {
    /// An empty buffer for `items` data items holding at most `capacity` observations.
    pub fn new(items: usize, capacity: usize) -> Buffer {
        Buffer {
            ring: VecDeque::new(),
            capacity: capacity.max(1),
            next: 1,
            base: vec![ItemState::default(); items],
            latest: vec![ItemState::default(); items],
        }
    }

    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Appends an observation; returns its sequence number.
    pub fn push(&mut self, time_ns: u64, item: usize, value: Value) -> u64 {
        if self.ring.len() == self.capacity
            && let Some(old) = self.ring.pop_front()
        {
            self.base[old.item].apply(&old);
        }
        if self.ring.len() == self.ring.capacity() {
            // Doubling, but not past the configured size.
            let more = self.ring.len().max(16).min(self.capacity - self.ring.len());
            self.ring.reserve_exact(more);
        }
        let o = Observation {
            sequence: self.next,
            time_ns,
            item,
            value,
        };
        self.next += 1;
        self.latest[item].apply(&o);
        self.ring.push_back(o);
        self.next - 1
    }

    /// The latest state of `item`.
    pub fn latest(&self, item: usize) -> &ItemState {
        &self.latest[item]
    }

    /// Sequence of the oldest observation held (`next_sequence` when empty).
    pub fn first_sequence(&self) -> u64 {
        self.ring.front().map_or(self.next, |o| o.sequence)
    }

    /// Sequence of the newest observation (0 before the first).
    pub fn last_sequence(&self) -> u64 {
        self.next - 1
    }

    /// The sequence the next observation will get.
    pub fn next_sequence(&self) -> u64 {
        self.next
    }

    /// Every item's state as of sequence `at` (`None`: now).
    pub fn state_at(&self, at: Option<u64>) -> Result<Vec<ItemState>, OutOfRange> {
        let Some(at) = at else {
            return Ok(self.latest.clone());
        };
        let (first, last) = (self.first_sequence(), self.last_sequence());
        if at < first || at > last {
            return Err(OutOfRange {
                param: "at",
                value: at,
                first,
                last,
            });
        }
        let mut s = self.base.clone();
        for o in self.ring.iter().take_while(|o| o.sequence <= at) {
            s[o.item].apply(o);
        }
        Ok(s)
    }

    /// Up to `count` observations from sequence `from` that `wanted` accepts, and the sequence
    /// to ask for next. `from` may be the next sequence (nothing new yet).
    pub fn sample(
        &self,
        from: u64,
        count: usize,
        wanted: impl Fn(usize) -> bool,
    ) -> Result<(Vec<Observation>, u64), OutOfRange> {
        let first = self.first_sequence();
        if from < first || from > self.next {
            return Err(OutOfRange {
                param: "from",
                value: from,
                first,
                last: self.next,
            });
        }
        let mut out = Vec::new();
        let mut next = self.next;
        for o in self.ring.iter().skip((from - first) as usize) {
            if out.len() == count {
                next = o.sequence;
                break;
            }
            if wanted(o.item) {
                out.push(o.clone());
            }
        }
        Ok((out, next))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fault(code: &str) -> Value {
        Value::Condition(Box::new(Cond {
            level: Level::Fault,
            native_code: Some(code.into()),
            qualifier: None,
            message: "m".into(),
        }))
    }

    #[test]
    fn sequences_have_no_gaps_and_the_ring_keeps_the_last_observations() {
        let mut b = Buffer::new(2, 4);
        for i in 0..10 {
            assert_eq!(b.push(i, (i % 2) as usize, Value::Number(i as f64)), i + 1);
        }
        assert_eq!((b.first_sequence(), b.last_sequence()), (7, 10));
        let (obs, next) = b.sample(7, 100, |_| true).unwrap();
        let seqs: Vec<u64> = obs.iter().map(|o| o.sequence).collect();
        assert_eq!((seqs, next), (vec![7, 8, 9, 10], 11));
        let (obs, next) = b.sample(7, 2, |_| true).unwrap();
        assert_eq!((obs.len(), next), (2, 9));
        assert_eq!(b.sample(11, 5, |_| true).unwrap().0, vec![]);
        assert_eq!(b.sample(6, 5, |_| true).unwrap_err().param, "from");
        assert!(b.sample(12, 5, |_| true).is_err());
    }

    #[test]
    fn the_ring_grows_as_observations_come_up_to_its_size() {
        // What the documented memory of a full ring rests on (docs/mtconnect.md).
        assert!(std::mem::size_of::<Observation>() <= 56);
        let mut b = Buffer::new(1, 100);
        assert_eq!(b.ring.capacity(), 0);
        for i in 0..30 {
            b.push(i, 0, Value::Number(0.0));
        }
        assert!(
            (30..100).contains(&b.ring.capacity()),
            "{}",
            b.ring.capacity()
        );
        for i in 30..250 {
            b.push(i, 0, Value::Number(0.0));
        }
        assert_eq!((b.ring.len(), b.ring.capacity()), (100, 100));
    }

    #[test]
    fn current_at_replays_from_the_state_before_the_ring() {
        let mut b = Buffer::new(1, 3);
        for i in 1..=6 {
            b.push(i, 0, Value::Number(i as f64));
        }
        let s = b.state_at(Some(5)).unwrap();
        assert_eq!(s[0].last.as_ref().unwrap().value, Value::Number(5.0));
        assert!(b.state_at(Some(3)).is_err());
        assert!(b.state_at(Some(7)).is_err());
    }

    #[test]
    fn conditions_stay_active_until_their_code_clears() {
        let mut b = Buffer::new(1, 10);
        b.push(1, 0, fault("a"));
        b.push(2, 0, fault("b"));
        assert_eq!(b.latest(0).shown().count(), 2);
        b.push(
            3,
            0,
            Value::Condition(Box::new(Cond {
                level: Level::Normal,
                native_code: Some("a".into()),
                qualifier: None,
                message: String::new(),
            })),
        );
        let shown: Vec<_> = b.latest(0).shown().map(|o| o.sequence).collect();
        assert_eq!(shown, vec![2]);
        b.push(
            4,
            0,
            Value::Condition(Box::new(Cond {
                level: Level::Normal,
                native_code: None,
                qualifier: None,
                message: String::new(),
            })),
        );
        let shown: Vec<_> = b.latest(0).shown().map(|o| o.sequence).collect();
        assert_eq!(shown, vec![4]);
    }
}
