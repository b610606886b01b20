//! Runs the paper's Figure 4 program (deliverMail) on virtual time and prints TCM's text log.
//!
//! `cargo run -p tcm --example deliver_mail` (add `-- --never-centred` to watch the 30 s timeout
//! cut a door search that never converges, `-- --monitor` for the Figure 6 pickup monitor instead
//! of its stand-in, `-- --time` for timestamps).

#[path = "paper/fig4.rs"]
mod fig4;

use tcm::{Runtime, TextLogSink};
use tcm_trace::TextLogOptions;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    for a in &args {
        if !matches!(a.as_str(), "--never-centred" | "--time" | "--monitor") {
            eprintln!("unknown argument {a:?}; expected --never-centred, --monitor and/or --time");
            std::process::exit(2);
        }
    }
    let world = if args.iter().any(|a| a == "--never-centred") {
        fig4::World::never_centred()
    } else {
        fig4::World::nominal()
    };
    let options = TextLogOptions {
        time: args.iter().any(|a| a == "--time"),
        ..TextLogOptions::default()
    };
    let monitor = args.iter().any(|a| a == "--monitor");
    let report = tcm::block_on_virtual(async move {
        Runtime::new()
            .with_sink(TextLogSink::with_options(std::io::stdout(), options))
            .run(if monitor {
                fig4::deliver_mail_fig6(7, world)
            } else {
                fig4::deliver_mail(7, world)
            })
            .await
    })?;
    eprintln!(
        "outcome: {:?} after {:?} of virtual time",
        report.outcome, report.elapsed
    );
    Ok(())
}
