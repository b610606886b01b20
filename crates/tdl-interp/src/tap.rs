//! Wiretaps a program declares (`wiretap w(args) before|after T { … }`), built as the generated
//! code builds them: a `tdl::Tap` on `T` whose check runs the body, its arguments (if it declares
//! any) read from the node it checks.

use std::sync::Arc;

use tdl::{Ctx, Failure, Tap, TapWhen};

use crate::program::{Program, Shared, intern, run};
use crate::value::Args;

impl Program {
    /// The wiretaps the program declares, to give to a run (`Runtime::tap`, `Control::tap`).
    pub fn taps(&self) -> Vec<Tap> {
        self.shared
            .tasks
            .iter()
            .enumerate()
            .filter_map(|(idx, def)| {
                let (after, target) = def.tap.as_ref()?;
                Some(tap(&self.shared, idx, *after, target))
            })
            .collect()
    }

    /// The tasks its wiretaps check, in declaration order.
    pub fn tapped_tasks(&self) -> Vec<String> {
        self.shared
            .tasks
            .iter()
            .filter_map(|d| d.tap.as_ref().map(|(_, t)| t.to_string()))
            .collect()
    }
}

/// The wiretap `idx`, checking `target` before or `after`.
fn tap(shared: &Arc<Shared>, idx: usize, after: bool, target: &str) -> Tap {
    let def = &shared.tasks[idx];
    let name = def.name;
    let reads = !def.params.is_empty();
    let s = shared.clone();
    let when = if after {
        TapWhen::After
    } else {
        TapWhen::Before
    };
    let target = intern(target);
    Tap::new(target, when, move |ctx: Ctx| {
        let s = s.clone();
        async move {
            let args = if reads {
                match ctx.tapped_args::<Args>() {
                    Some(a) => a.0.clone(),
                    None => {
                        return Err(Failure::new(
                            "NotTapped",
                            format!(
                                "`{name}` ran on a node that is no `{target}` keeping its arguments, so it has no arguments to read"
                            ),
                        ));
                    }
                }
            } else {
                Vec::new()
            };
            run(s, idx, ctx, args, None).await
        }
    })
}
