//! A Bus through real COM ports on Windows. `.ci/cross-windows.sh` runs these under wine
//! (`cargo test --target x86_64-pc-windows-gnu --test windows_com -- --ignored`), with COM
//! ports of its wine prefix mapped to pseudo-terminals that simulators serve on the Linux side
//! (`benchbus sim instrument`: the Taisong meter, unit 1):
//!
//! - `BENCHBUS_COM`: a COM port below 10 with a simulator behind it;
//! - `BENCHBUS_COM_HIGH`: a COM port from 10 on, with a simulator behind it;
//! - `BENCHBUS_COM_UNPLUG`: a COM port with a simulator behind it that the script stops when
//!   the file `unplug` appears in the directory `BENCHBUS_COM_CONTROL`, then starts again on
//!   the same COM port, and says so with the file `replugged` there.
//!
//! Each test uses its COM port alone; the script runs them one at a time.
//!
//! Not here: a second open of a COM port a Bus holds. Windows refuses it (the serialport
//! crate opens without sharing), wine does not for a device; the unit tests of
//! `transport::windows` check how the refusal is told, on a file wine does refuse.
#![cfg(windows)]

use benchbus::bus::{Bus, BusConfig, TxOptions};
use benchbus::timing::{LineFormat, Parity};
use benchbus::Error;
use std::path::PathBuf;
use std::time::{Duration, Instant};

const WHY: &str = "needs COM ports served by simulators: .ci/cross-windows.sh runs it";

/// The simulated meter's unit, a free table register pair, and its setpoint register.
const UNIT: u8 = 1;
const TABLE: u16 = 0x0008;
const SV: u16 = 0x0005;

fn env(name: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| panic!("{name} is not set: {WHY}"))
}

fn config(port: &str) -> BusConfig {
    let mut cfg = BusConfig::new(port, LineFormat::new(19_200, Parity::None, 1)).unwrap();
    cfg.timeout = Duration::from_millis(500);
    cfg
}

fn opts() -> TxOptions {
    TxOptions::default()
}

fn port_message(e: &Error) -> String {
    match e {
        Error::Port { message, .. } => message.clone(),
        other => panic!("not a port error: {other:?}"),
    }
}

/// Writes and reads back a block and a single register.
fn round_trip(bus: &Bus, seed: u16) {
    bus.write_registers(UNIT, TABLE, &[seed, seed + 1], &opts())
        .unwrap();
    assert_eq!(
        bus.read_holding_registers(UNIT, TABLE, 2, &opts()).unwrap(),
        [seed, seed + 1]
    );
    bus.write_register(UNIT, SV, seed + 2, &opts()).unwrap();
    assert_eq!(
        bus.read_holding_registers(UNIT, SV, 1, &opts()).unwrap(),
        [seed + 2]
    );
}

#[test]
#[ignore = "needs COM ports served by simulators: .ci/cross-windows.sh runs it"]
fn registers_are_read_and_written_through_a_com_port() {
    let bus = Bus::open(config(&env("BENCHBUS_COM"))).unwrap();
    round_trip(&bus, 100);
    let stats = bus.stats();
    assert_eq!((stats.transactions, stats.timeouts), (4, 0));
}

#[test]
#[ignore = "needs COM ports served by simulators: .ci/cross-windows.sh runs it"]
fn com10_and_up_open_by_the_name_windows_shows() {
    let port = env("BENCHBUS_COM_HIGH");
    let bus = Bus::open(config(&port)).unwrap();
    assert_eq!(bus.config().port(), port);
    round_trip(&bus, 200);
}

#[test]
#[ignore = "needs COM ports served by simulators: .ci/cross-windows.sh runs it"]
fn an_absent_unit_times_out_within_its_bound() {
    let mut cfg = config(&env("BENCHBUS_COM"));
    cfg.timeout = Duration::from_millis(200);
    cfg.retries = 1;
    let bus = Bus::open(cfg).unwrap();
    let start = Instant::now();
    let e = bus
        .read_holding_registers(9, TABLE, 1, &opts())
        .unwrap_err();
    let took = start.elapsed();
    assert!(
        matches!(
            e,
            Error::Timeout {
                unit: 9,
                attempts: 2,
                ..
            }
        ),
        "{e:?}"
    );
    // Two attempts of 200 ms, the request's wire time and t3.5 between them; a COM timeout
    // rounded to the system's ticks would still fit, one that never fired would not.
    assert!(
        took >= Duration::from_millis(400) && took < Duration::from_millis(700),
        "{took:?}"
    );
    // The unit that is there still answers on the same port.
    round_trip(&bus, 300);
}

#[test]
#[ignore = "needs COM ports served by simulators: .ci/cross-windows.sh runs it"]
fn a_com_port_that_does_not_exist_is_told_with_the_ports_there_are() {
    let Err(e) = Bus::open(config("COM199")) else {
        panic!("COM199 opened");
    };
    let message = port_message(&e);
    assert!(message.starts_with("cannot open: "), "{message}");
    let listed = benchbus::transport::ports::list_ports().unwrap();
    let names: Vec<&str> = listed.iter().map(|p| p.path.as_str()).collect();
    assert!(!names.contains(&"COM199"), "{names:?}");
    if names.is_empty() {
        assert!(
            message.ends_with("(this system lists no serial ports)"),
            "{message}"
        );
    } else {
        assert!(
            message.ends_with(&format!("(the serial ports here: {})", names.join(", "))),
            "{message}"
        );
    }
}

/// Waits (boundedly) for the file `name` in the control directory.
fn await_file(dir: &std::path::Path, name: &str) {
    let start = Instant::now();
    while !dir.join(name).exists() {
        assert!(start.elapsed() < Duration::from_secs(20), "no {name} file");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
#[ignore = "needs COM ports served by simulators: .ci/cross-windows.sh runs it"]
fn an_unplugged_com_port_is_lost_and_reconnect_brings_it_back() {
    let port = env("BENCHBUS_COM_UNPLUG");
    let control = PathBuf::from(env("BENCHBUS_COM_CONTROL"));
    let mut cfg = config(&port);
    cfg.reconnect = true;
    cfg.retries = 0;
    let bus = Bus::open(cfg).unwrap();
    round_trip(&bus, 600);

    std::fs::write(control.join("unplug"), b"").unwrap();
    // The far end goes away: the first call that meets it fails as lost, at once rather
    // than after its timeout (one the simulator's end took in the middle times out).
    // After a call that timed out, the next one first listens for the answer the unit owes
    // (up to three timeouts), and a port gone under wine reads as silence until then.
    let start = Instant::now();
    let mut owed = Duration::ZERO;
    let (lost, took) = loop {
        assert!(start.elapsed() < Duration::from_secs(10), "never lost");
        let call = Instant::now();
        match bus.read_holding_registers(UNIT, TABLE, 2, &opts()) {
            Err(e @ Error::Port { .. }) => break (e, call.elapsed()),
            Ok(_) => owed = Duration::ZERO,
            Err(Error::Timeout { .. }) => owed = 3 * bus.timeout(),
            Err(e) => panic!("{e:?}"),
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let message = port_message(&lost);
    // Met before anything of the call was written (in the stale-input check), the loss is
    // followed by a reopen in the same call, which fails while the port is gone.
    assert!(
        message.starts_with("lost: gone (unplugged?): ")
            && message.ends_with("(the next call tries to reopen it)")
            || message.starts_with("lost (gone (unplugged?): ")
                && message.contains("); tried to reopen it: cannot open: "),
        "{message}"
    );
    assert!(
        took < owed + Duration::from_millis(100),
        "{took:?} ({owed:?} owed)"
    );
    assert!(bus.is_lost());

    // Plugged in again only now: a far end served again before the loss was met (a new
    // simulator on the same pseudo-terminal number) would let the reopen hide it.
    std::fs::write(control.join("lost"), b"").unwrap();
    await_file(&control, "replugged");
    let start = Instant::now();
    let values = loop {
        match bus.read_holding_registers(UNIT, TABLE, 2, &opts()) {
            Ok(values) => break values,
            Err(e) => {
                assert!(start.elapsed() < Duration::from_secs(10), "not back: {e}");
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    };
    // A fresh simulator: its table starts at 0.
    assert_eq!(values, [0, 0]);
    assert!(!bus.is_lost());
    assert!(bus.stats().reopens >= 1);
    round_trip(&bus, 700);
}
