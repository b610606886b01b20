//! The paper's Figure 4, `deliverMail` and `centerOnDoor`, written with the `tcm` API over a tiny
//! simulated world. Shared by the `deliver_mail` example and the runtime's story tests.
//!
//! ```text
//! Goal deliverMail (int room) {
//!     spawn navigateToLocn(x, y);
//!     spawn centerOnDoor(x, y) with sequential execution previous, terminate in 0:0:30.0;
//!     spawn speak("Xavier here with your mail")
//!         with sequential execution centerOnDoor, terminate at monitorPickup completed;
//!     spawn monitorPickup() with sequential execution centerOnDoor;
//! }
//! Goal centerOnDoor (double x, double y) delay expansion {
//!     spawn lookForDoor(&whichSide) with wait;
//!     if (whichSide != 0) {
//!         spawn move(whichSide < 0 ? -10 : 10);
//!         spawn centerOnDoor(x, y) with disable execution until previous execution completed;
//!     }
//! }
//! ```
//!
//! `monitorPickup` is the Figure 6 monitor ([`monitor_pickup`]) or, in [`deliver_mail`], a plain
//! command standing in for it, as in the runtime's first story tests.

#![allow(dead_code, unreachable_pub)]

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tcm::{Constraint, Event, Facet, Monitor, NodeRef, Point, Task, When};

/// The simulated world: what the door sensor will report, and when the mail is taken.
pub struct World {
    /// Successive readings of the door sensor: negative = door to the left, positive = right,
    /// zero = centred. When empty, the sensor keeps reporting `forever`.
    pub door_readings: Mutex<VecDeque<i32>>,
    /// The reading once the list is exhausted.
    pub forever: i32,
    /// How long after `monitor_pickup` starts the mail is taken (for the stand-in command), or when,
    /// since the run started, it is taken (for the Figure 6 monitor).
    pub pickup_after: Duration,
    /// What the robot said, in order.
    pub said: Mutex<Vec<String>>,
}

impl World {
    /// A door found after two corrections.
    pub fn nominal() -> Arc<World> {
        Arc::new(World {
            door_readings: Mutex::new(VecDeque::from([-1, 1])),
            forever: 0,
            pickup_after: Duration::from_secs(5),
            said: Mutex::new(Vec::new()),
        })
    }

    /// A door search that never converges: the 30 s timeout must cut it.
    pub fn never_centred() -> Arc<World> {
        Arc::new(World {
            door_readings: Mutex::new(VecDeque::new()),
            forever: 1,
            pickup_after: Duration::from_secs(5),
            said: Mutex::new(Vec::new()),
        })
    }

    /// The sensor reading when looking for the door of the room at `(x, y)` (the simulation
    /// ignores where: it replays its list).
    fn read_door(&self, x: f64, y: f64) -> i32 {
        debug_assert!(x.is_finite() && y.is_finite());
        match self.door_readings.lock() {
            Ok(mut q) => q.pop_front().unwrap_or(self.forever),
            Err(_) => self.forever,
        }
    }
}

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// A command that takes `d` of (virtual) time.
fn busy(name: &'static str, d: Duration) -> Task {
    Task::command(name, move |_| async move {
        tokio::time::sleep(d).await;
        Ok(())
    })
}

/// `Goal deliverMail(int room)`, with a command standing in for the monitor.
pub fn deliver_mail(room: u32, world: Arc<World>) -> Task {
    deliver_mail_with(room, world, |w| busy("monitorPickup", w.pickup_after))
}

/// `Goal deliverMail(int room)` with the Figure 6 monitor.
pub fn deliver_mail_fig6(room: u32, world: Arc<World>) -> Task {
    deliver_mail_with(room, world, monitor_pickup)
}

/// ```text
/// Monitor monitorPickup () max triggers = 1, max activations = 15, period = 0:0:1.5 {
///     if (mailIsGone()) {
///         trigger;
///         with (parallel) do { spawn speak("Thank you"); spawn notifySender(); }
///     }
/// }
/// ```
pub fn monitor_pickup(world: Arc<World>) -> Task {
    let params = Monitor {
        max_triggers: Some(1),
        max_activations: Some(15),
        period: Some(Duration::from_millis(1500)),
        ..Monitor::default()
    };
    Task::monitor("monitorPickup", params, move |ctx| {
        let w = world.clone();
        async move {
            if ctx.now() >= w.pickup_after {
                ctx.trigger()?;
                ctx.spawn(say("Thank you", w.clone())).start()?;
                ctx.spawn(busy("notifySender", Duration::from_millis(500)))
                    .start()?;
            }
            Ok(())
        }
    })
}

fn say(text: &'static str, world: Arc<World>) -> Task {
    Task::command("speak", move |_| async move {
        if let Ok(mut said) = world.said.lock() {
            said.push(text.to_string());
        }
        tokio::time::sleep(secs(1)).await;
        Ok(())
    })
}

fn deliver_mail_with(room: u32, world: Arc<World>, pickup: fn(Arc<World>) -> Task) -> Task {
    Task::goal("deliverMail", move |ctx| async move {
        let (x, y) = (f64::from(room) * 10.0, 5.0);
        ctx.spawn(navigate_to_locn(x, y)).start()?;
        let center = ctx
            .spawn(center_on_door(x, y, world.clone()))
            .sequential(Facet::Execution, NodeRef::Previous)
            .terminate_in(secs(30))
            .start()?;
        // `speak` names `monitorPickup`, spawned after it: a forward reference.
        let monitor = ctx.reserve("monitorPickup")?;
        ctx.spawn(speak("Xavier here with your mail"))
            .sequential(Facet::Execution, center)
            .terminate_at(Event::new(monitor, Point::Completed))
            .start()?;
        ctx.spawn(pickup(world.clone()))
            .sequential(Facet::Execution, center)
            .fulfils(monitor)
            .start()?;
        Ok(())
    })
}

/// `Goal navigateToLocn(double x, double y)`: three legs of travel, one after the other.
pub fn navigate_to_locn(_x: f64, _y: f64) -> Task {
    Task::goal("navigateToLocn", |ctx| async move {
        for _ in 0..3 {
            ctx.spawn(busy("move", secs(2)))
                .sequential(Facet::Execution, NodeRef::Previous)
                .start()?;
        }
        Ok(())
    })
}

/// `Goal centerOnDoor(double x, double y) delay expansion`.
pub fn center_on_door(x: f64, y: f64, world: Arc<World>) -> Task {
    Task::goal("centerOnDoor", move |ctx| async move {
        let w = world.clone();
        let which_side: i32 = ctx
            .spawn(Task::command("lookForDoor", move |_| async move {
                tokio::time::sleep(secs(1)).await;
                Ok(w.read_door(x, y))
            }))
            .wait_value()
            .await?;
        if which_side != 0 {
            ctx.spawn(busy("move", secs(1))).start()?;
            ctx.spawn(center_on_door(x, y, world))
                .with(Constraint::disable(
                    Facet::Execution,
                    When::Event(Event::on(
                        NodeRef::Previous,
                        Facet::Execution,
                        Point::Completed,
                    )),
                ))
                .start()?;
        }
        Ok(())
    })
    .with(Constraint::DelayExpansion)
}

/// `Command speak(string text)`: keeps repeating its announcement until terminated.
pub fn speak(_text: &'static str) -> Task {
    Task::command("speak", |_| async move {
        // The announcement repeats until `terminate at monitorPickup completed` cancels it.
        std::future::pending::<()>().await;
        Ok(())
    })
}
