//! `biasctl demo`: simulate the paper's tables, a dwell run and a random run into one folder.

use anyhow::Context;
use biasctl::sim::{Drive, SequenceOptions, SimConfig, simulate_to_files};
use std::path::PathBuf;

/// Flags of `biasctl demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/demo", value_name = "DIR")]
    out: PathBuf,
    /// Seed for every run.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Writes `<seq>.csv` and `<seq>_truth.csv` for table1..table7, dwell and random.
pub fn run(args: Args) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let names = [
        "table1", "table2", "table3", "table4", "table5", "table6", "table7", "dwell", "random",
    ];
    println!("demo: drive paper1997, seed {}", args.seed);
    for name in names {
        let cfg = SimConfig::new(
            Drive::paper1997(),
            name,
            &SequenceOptions::default(),
            args.seed,
            &[],
        )?;
        let log = args.out.join(format!("{name}.csv"));
        let truth = args.out.join(format!("{name}_truth.csv"));
        let s = simulate_to_files(&cfg, &log, Some(&truth))?;
        println!(
            "  {name:<7} {:>5} rows ({:>5} measured) -> {} (truth: {})",
            s.rows,
            s.measured,
            log.display(),
            truth.display()
        );
    }
    Ok(())
}
