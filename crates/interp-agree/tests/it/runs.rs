//! The programs the interpreter runs, one module each: the compiled program included from
//! `$OUT_DIR`, the Rust items it calls, the registry of the same items for the interpreter, and
//! the runs of its goals and commands compared.

mod allowed_warnings;
mod approvals;
mod attached_handlers;
mod attached_to_extern;
mod blocking_commands;
mod bounded_recursion;
mod exceptions_handlers;
mod external_events;
mod fig4_deliver_mail;
mod fig6_monitor_pickup;
mod forward_references;
mod handled_exceptions;
mod handlers_retry;
mod logging;
mod loops_iteration_tags;
mod near_cycles;
mod node_refs_bind_parent;
mod outcome_events;
mod propagation;
mod resources;
mod waits_in_order;
mod with_groups_deliver_mail;
