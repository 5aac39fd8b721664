//! The long link-fault soak: the host client and the simulated device over a
//! seeded faulty link, with its figures.
//!
//!   cargo run --release -p system-tests --example link_soak -- --frames 100000 --seed 1
//!
//! Exits non-zero if any point was lost, repeated or altered without the host
//! knowing (the run also panics, with the seed, on any broken property).
use system_tests::link_faults::{FaultRates, SoakConfig, soak};

fn main() {
    let mut cfg = SoakConfig { frames: 100_000, seed: 1, rates: FaultRates::SOAK };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| -> u64 {
            let v = args.next().unwrap_or_else(|| die(&format!("{name} needs a number")));
            v.parse().unwrap_or_else(|_| die(&format!("{name}: {v:?} is not a number")))
        };
        match a.as_str() {
            "--frames" => cfg.frames = value("--frames"),
            "--seed" => cfg.seed = value("--seed"),
            "-h" | "--help" => {
                println!("usage: link_soak [--frames N (100000)] [--seed S (1)]");
                return;
            }
            other => die(&format!("unknown argument {other:?} (try --help)")),
        }
    }
    println!("link soak: {} frames at least, seed {}, rates {:?}", cfg.frames, cfg.seed, cfg.rates);
    let r = soak(cfg);
    println!("{r}");
    if r.undetected != 0 {
        std::process::exit(1);
    }
}

fn die(msg: &str) -> ! {
    eprintln!("link_soak: {msg}");
    std::process::exit(2);
}
