//! Handles: the generational slot map `Slots` of every kind of handle (contexts, models and
//! crowds here, palette models in `palette.rs`), the registry of the runtime's objects behind
//! one global lock, and the lookups from a handle to its object.

use super::guard::Failure;
use super::types::{RrskinContext, RrskinCrowd, RrskinModel};
use crate::model::Model;
use crate::vk::{Batch, Context, Crowd, GpuModel};
use std::sync::{Arc, Mutex, MutexGuard, RwLock, RwLockReadGuard, RwLockWriteGuard};

/// A slot map. A handle is `kind << 60 | generation << 28 | (index + 1)`: 0 is never a handle,
/// a destroyed slot's old handles stop matching, and a handle of one kind (say a crowd) never
/// matches another kind's slots (a context).
pub(super) struct Slots<T> {
    kind: u64,
    entries: Vec<(u32, Option<T>)>,
}

const INDEX_BITS: u32 = 28;

impl<T> Slots<T> {
    pub(super) const fn new(kind: u64) -> Self {
        Slots {
            kind,
            entries: Vec::new(),
        }
    }

    pub(super) fn insert(&mut self, value: T) -> u64 {
        let index = match self.entries.iter().position(|(_, v)| v.is_none()) {
            Some(i) => i,
            None => {
                self.entries.push((0, None));
                self.entries.len() - 1
            }
        };
        debug_assert!(
            index + 1 < 1 << INDEX_BITS,
            "more than 2^28 live handles of one kind"
        );
        let slot = &mut self.entries[index];
        slot.0 = slot.0.wrapping_add(1);
        slot.1 = Some(value);
        (self.kind << 60) | ((slot.0 as u64) << INDEX_BITS) | (index as u64 + 1)
    }

    fn locate(&self, id: u64) -> Option<usize> {
        if id >> 60 != self.kind {
            return None;
        }
        let index = (id & ((1 << INDEX_BITS) - 1)).checked_sub(1)? as usize;
        let generation = ((id >> INDEX_BITS) & 0xFFFF_FFFF) as u32;
        match self.entries.get(index) {
            Some((g, Some(_))) if *g == generation => Some(index),
            _ => None,
        }
    }

    pub(super) fn get(&self, id: u64) -> Result<&T, Failure> {
        self.locate(id)
            .and_then(|i| self.entries[i].1.as_ref())
            .ok_or(Failure::invalid_handle())
    }

    pub(super) fn remove(&mut self, id: u64) -> Result<T, Failure> {
        let i = self.locate(id).ok_or(Failure::invalid_handle())?;
        self.entries[i].1.take().ok_or(Failure::invalid_handle())
    }
}

/// The registry's entries are shared (`Arc`) so that a call holds the global lock only to find
/// its objects, and each object's own lock (the batch's mutex, the crowd's read-write lock)
/// for the work.
pub(super) struct ContextEntry {
    pub(super) context: Context,
    pub(super) batch: Mutex<Batch>,
}

/// Immutable once loaded.
pub(super) struct ModelEntry {
    pub(super) model: Model,
    pub(super) gpu: GpuModel,
}

impl ContextEntry {
    pub(super) fn batch(&self) -> MutexGuard<'_, Batch> {
        self.batch
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

pub(super) struct CrowdEntry {
    /// Its context's device, to check for a lost device without taking the crowd's lock.
    pub(super) device: Context,
    pub(super) crowd: RwLock<Crowd>,
}

impl CrowdEntry {
    pub(super) fn read(&self) -> RwLockReadGuard<'_, Crowd> {
        self.crowd
            .read()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    pub(super) fn write(&self) -> RwLockWriteGuard<'_, Crowd> {
        self.crowd
            .write()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

pub(super) struct Registry {
    pub(super) contexts: Slots<Arc<ContextEntry>>,
    pub(super) models: Slots<Arc<ModelEntry>>,
    pub(super) crowds: Slots<Arc<CrowdEntry>>,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    contexts: Slots::new(1),
    models: Slots::new(2),
    crowds: Slots::new(3),
});

pub(super) fn registry() -> MutexGuard<'static, Registry> {
    REGISTRY
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The objects behind handles, found under the global lock and used after it is released; each
/// fails at once on a lost device.
pub(super) fn context_entry(context: RrskinContext) -> Result<Arc<ContextEntry>, Failure> {
    let entry = registry().contexts.get(context.id)?.clone();
    entry.context.check_lost()?;
    Ok(entry)
}

pub(super) fn model_entry(model: RrskinModel) -> Result<Arc<ModelEntry>, Failure> {
    let entry = registry().models.get(model.id)?.clone();
    entry.gpu.context().check_lost()?;
    Ok(entry)
}

pub(super) fn crowd_entry(crowd: RrskinCrowd) -> Result<Arc<CrowdEntry>, Failure> {
    let entry = registry().crowds.get(crowd.id)?.clone();
    entry.device.check_lost()?;
    Ok(entry)
}
