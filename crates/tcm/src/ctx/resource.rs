//! What an action asks of the run's resources (docs/semantics.md, "Resources"): reserve,
//! unreserve, lock, unlock and read.

use super::Ctx;
use crate::Error;
use crate::resource::{ResourceRef, resource_for};
use tcm_core::{NodeId, ResourceInfo};

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
        let r = resource_for(&mut inner.engine, &resource.into())?;
        Ok(inner.engine.reserve_resource(now, r, holder)?)
    }

    /// Ends the reservation of `resource`, if it has one. TDL's `unreserve r;`.
    pub fn unreserve_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = resource_for(&mut inner.engine, &resource.into())?;
        Ok(inner.engine.unreserve_resource(now, r)?)
    }

    /// Locks `resource`: nobody is granted it until it is unlocked; grants already made stay
    /// (TCA's lock). TDL's `lock r;`.
    pub fn lock_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = resource_for(&mut inner.engine, &resource.into())?;
        Ok(inner.engine.lock_resource(now, r)?)
    }

    /// Unlocks `resource`. TDL's `unlock r;`.
    pub fn unlock_resource(&self, resource: impl Into<ResourceRef>) -> Result<(), Error> {
        let mut inner = self.shared.enter()?;
        let now = inner.engine.at_clock();
        let r = resource_for(&mut inner.engine, &resource.into())?;
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
