//! Resources as the runtime offers them (docs/semantics.md, "Resources"): declared on the
//! [`Runtime`](crate::Runtime) (or on first use, from a [`Resource`] a spawn names), used by a
//! task or a spawn ([`Task::uses`](crate::Task::uses), [`Spawner::uses`](crate::Spawner::uses)),
//! reserved and locked from an action ([`Ctx::reserve_resource`], [`Ctx::lock_resource`]) or the
//! program ([`Session::lock_resource`](crate::Session::lock_resource)). The engine does the
//! granting; this module turns names into the engine's resource handles under the lock, and makes
//! the engine's refusals typed exceptions a handler takes by name.

use crate::Error;
use crate::ctx::Ctx;
use crate::host::Inner;
use crate::task::Exception;
use tcm_core::{EngineError, Name, NodeId, ResourceId, ResourceInfo, Uses};

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

impl Inner {
    /// Declares `r` (an error if its name is taken, or its capacity is 0).
    pub(crate) fn declare(&mut self, r: &Resource) -> Result<ResourceId, EngineError> {
        self.engine
            .declare_resource(r.name.clone(), r.capacity, r.pending_limit)
    }

    /// The engine's uses for `wanted`: each name resolved, each declaration declared if new.
    pub(crate) fn resolve(&mut self, wanted: Wanted) -> Result<Option<Box<Uses>>, EngineError> {
        if wanted.uses.is_empty() {
            return Ok(None);
        }
        let mut uses = Uses {
            amounts: Vec::with_capacity(wanted.uses.len()),
            priority: wanted.priority.unwrap_or(0),
            deny_if_busy: wanted.deny_if_busy,
        };
        for (r, amount) in wanted.uses {
            let id = self.resource_for(&r)?;
            uses.amounts.push((id, amount));
        }
        Ok(Some(Box::new(uses)))
    }

    /// The resource `r` names: the run's resource of that name, or, for a declaration the run
    /// does not have yet, the resource it declares now.
    pub(crate) fn resource_for(&mut self, r: &ResourceRef) -> Result<ResourceId, EngineError> {
        match (&r.0, self.engine.resource_id(r.name())) {
            (_, Some(id)) => Ok(id),
            (Ref::Declared(decl), None) => self.declare(decl),
            (Ref::Named(name), None) => Err(EngineError::UnknownResource(name.to_string())),
        }
    }
}

impl Ctx {
    /// Reserves `resource` (a name the run declared, or a [`Resource`], declared on first use) for
    /// `holder` (TCA: a resource reserved for one module): until it is unreserved, or the holder's
    /// execution completes, only `holder` and its descendants are granted it; others wait
    /// (docs/semantics.md, "Resources"). TDL's `reserve r;`.
    pub fn reserve_resource(
        &self,
        resource: impl Into<ResourceRef>,
        holder: NodeId,
    ) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = inner.resource_for(&resource.into())?;
        Ok(inner.engine.reserve_resource(now, r, holder)?)
    }

    /// Ends the reservation of `resource`, if it has one. TDL's `unreserve r;`.
    pub fn unreserve_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = inner.resource_for(&resource.into())?;
        Ok(inner.engine.unreserve_resource(now, r)?)
    }

    /// Locks `resource`: nobody is granted it until it is unlocked; grants already made stay
    /// (TCA's lock). TDL's `lock r;`.
    pub fn lock_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = inner.resource_for(&resource.into())?;
        Ok(inner.engine.lock_resource(now, r)?)
    }

    /// Unlocks `resource`. TDL's `unlock r;`.
    pub fn unlock_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = inner.resource_for(&resource.into())?;
        Ok(inner.engine.unlock_resource(now, r)?)
    }

    /// The resource `name` now: its capacity, holders, waiting requests, reservation and lock.
    /// `None` if no resource of that name is declared.
    pub fn resource_info(&self, name: &str) -> Result<Option<ResourceInfo>, Error> {
        let inner = crate::host::lock(&self.shared)?;
        Ok(inner
            .engine
            .resource_id(name)
            .and_then(|r| inner.engine.resource_info(r)))
    }
}
