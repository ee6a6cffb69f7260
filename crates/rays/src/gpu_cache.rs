//! Bind groups kept while what they bind recurs: a pass that writes into a caller's buffer
//! (a network input tensor's storage, which burn's memory pool hands out again frame after
//! frame) makes its bind group once per (buffer, offset) instead of once per frame.

/// The values made for the last `capacity` distinct keys, newest last.
pub struct Recent<K, V> {
    entries: Vec<(K, V)>,
    capacity: usize,
}

impl<K: PartialEq, V> Recent<K, V> {
    pub fn new(capacity: usize) -> Recent<K, V> {
        Recent { entries: Vec::new(), capacity: capacity.max(1) }
    }

    /// The value kept for `key`, or the one `make` makes now (dropping the least recently
    /// used when full).
    pub fn get_or_make(&mut self, key: K, make: impl FnOnce() -> V) -> &V {
        let entry = match self.entries.iter().position(|(k, _)| *k == key) {
            Some(at) => self.entries.remove(at),
            None => {
                if self.entries.len() == self.capacity {
                    self.entries.remove(0);
                }
                (key, make())
            }
        };
        self.entries.push(entry);
        &self.entries.last().expect("pushed above").1
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recurring_key_is_made_once_and_the_least_recent_goes_first() {
        let made = std::cell::Cell::new(0);
        let mut recent = Recent::new(2);
        let mut get = |key: u32| {
            *recent.get_or_make(key, || {
                made.set(made.get() + 1);
                key * 10
            })
        };
        assert_eq!(get(1), 10);
        assert_eq!(get(2), 20);
        assert_eq!(get(1), 10);
        // 2 is now the least recently used: a third key drops it, not 1.
        assert_eq!(get(3), 30);
        assert_eq!(get(1), 10);
        assert_eq!(made.get(), 3);
        assert_eq!(get(2), 20);
        assert_eq!(made.get(), 4);
        assert_eq!(recent.len(), 2);
    }
}
