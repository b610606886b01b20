//! Resources as the runtime offers them (docs/semantics.md, "Resources"): declared on the
//! [`Runtime`](crate::Runtime) (or on first use, from a [`Resource`] a spawn names), used by a
//! task or a spawn ([`Task::uses`](crate::Task::uses), [`Spawner::uses`](crate::Spawner::uses)),
//! reserved and locked from an action ([`Ctx::reserve_resource`], [`Ctx::lock_resource`]) or the
//! program ([`Session::lock_resource`](crate::Session::lock_resource)). The engine does the
//! granting; this module turns names into the engine's resource handles under the lock, and makes
//! the engine's refusals typed exceptions a handler takes by name.

use crate::exception::Exception;
use tcm_core::{Engine, EngineError, Name, ResourceId, Uses};

pub use tcm_core::{ResourceDenied, ResourceDropped};

impl Exception for ResourceDenied {}
impl Exception for ResourceDropped {}
impl Exception for tcm_core::ApprovalRefused {}

/// A resource with its capacity and pending limit, as a declaration: given to
/// [`Runtime::declare`](crate::Runtime::declare), or to a spawn's `uses`, which declares it on
/// first use if the run has no resource of that name yet (a resource the run declared already is
/// used as it was declared). TDL's `resource arm(2) pending 4;` generates one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Resource {
    pub(crate) name: Name,
    pub(crate) capacity: u32,
    pub(crate) pending_limit: Option<u32>,
}

impl Resource {
    /// A resource `name` of `capacity` units, with no pending limit.
    pub fn new(name: impl Into<Name>, capacity: u32) -> Resource {
        Resource {
            name: name.into(),
            capacity,
            pending_limit: None,
        }
    }

    /// At most `n` requests wait for it; past it, the oldest waiting request is dropped and its
    /// node fails with [`ResourceDropped`].
    pub fn pending_limit(mut self, n: u32) -> Resource {
        self.pending_limit = Some(n);
        self
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

/// What a `uses` names: a resource declared on the run, by name, or a declaration used as is
/// (declared on first use).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResourceRef(Ref);

#[derive(Clone, Debug, PartialEq, Eq)]
enum Ref {
    Named(Name),
    Declared(Resource),
}

impl ResourceRef {
    fn name(&self) -> &Name {
        match &self.0 {
            Ref::Named(n) => n,
            Ref::Declared(r) => &r.name,
        }
    }
}

impl From<&'static str> for ResourceRef {
    fn from(name: &'static str) -> ResourceRef {
        ResourceRef(Ref::Named(Name::Borrowed(name)))
    }
}

impl From<String> for ResourceRef {
    fn from(name: String) -> ResourceRef {
        ResourceRef(Ref::Named(Name::Owned(name)))
    }
}

impl From<Resource> for ResourceRef {
    fn from(r: Resource) -> ResourceRef {
        ResourceRef(Ref::Declared(r))
    }
}

impl From<&Resource> for ResourceRef {
    fn from(r: &Resource) -> ResourceRef {
        ResourceRef(Ref::Declared(r.clone()))
    }
}

/// What a task or spawn asks of the run's resources, by name until it is spawned.
#[derive(Clone, Debug, Default)]
pub(crate) struct Wanted {
    pub(crate) uses: Vec<(ResourceRef, u32)>,
    pub(crate) priority: Option<i32>,
    pub(crate) deny_if_busy: bool,
}

/// Declares `r` (an error if its name is taken, or its capacity is 0).
pub(crate) fn declare<A, F: Clone>(
    engine: &mut Engine<A, F>,
    r: &Resource,
) -> Result<ResourceId, EngineError> {
    engine.declare_resource(r.name.clone(), r.capacity, r.pending_limit)
}

/// The engine's uses for `wanted`: each name resolved, each declaration declared if new.
pub(crate) fn resolve<A, F: Clone>(
    engine: &mut Engine<A, F>,
    wanted: Wanted,
) -> Result<Option<Box<Uses>>, EngineError> {
    if wanted.uses.is_empty() {
        return Ok(None);
    }
    let mut uses = Uses {
        amounts: Vec::with_capacity(wanted.uses.len()),
        priority: wanted.priority.unwrap_or(0),
        deny_if_busy: wanted.deny_if_busy,
    };
    for (r, amount) in wanted.uses {
        let id = resource_for(engine, &r)?;
        uses.amounts.push((id, amount));
    }
    Ok(Some(Box::new(uses)))
}

/// The resource `r` names: the run's resource of that name, or, for a declaration the run does
/// not have yet, the resource it declares now.
pub(crate) fn resource_for<A, F: Clone>(
    engine: &mut Engine<A, F>,
    r: &ResourceRef,
) -> Result<ResourceId, EngineError> {
    match (&r.0, engine.resource_id(r.name())) {
        (_, Some(id)) => Ok(id),
        (Ref::Declared(decl), None) => declare(engine, decl),
        (Ref::Named(name), None) => Err(EngineError::UnknownResource(name.to_string())),
    }
}
