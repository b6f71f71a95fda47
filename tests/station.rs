//! The station every device stands on: one place for the Bus, the unit and the device's own
//! timeout and retries, whichever family it is.

mod common;

use benchbus::device::drive::{Drive, Family};
use benchbus::device::instrument::Instrument;
use benchbus::device::j2::J2;
use benchbus::device::pbl::Pbl;
use benchbus::device::{Device, Table, Tabled};
use benchbus::Error;
use common::{bus, sent, words, Act};
use std::sync::Arc;
use std::time::Duration;

/// Three silent requests then a reply: how many a device sends shows its own retries.
fn silent_then_reply() -> Vec<Act> {
    vec![Act::Silent, Act::Silent, Act::Silent, words(7, &[42])]
}

fn instrument(bus: Arc<benchbus::bus::Bus>) -> Instrument {
    match Instrument::new(bus, 7, 37, 20, Duration::ZERO) {
        Ok(inst) => inst,
        Err(e) => panic!("valid limits: {e}"),
    }
}

/// What the station of `device` says: its timeout, retries and unit.
fn timing(device: &impl Device) -> (Duration, u32, u8) {
    let station = device.station();
    (station.timeout(), station.retries(), device.unit())
}

#[test]
fn without_its_own_timing_a_device_uses_the_buss() {
    let (b, _) = bus(vec![], 2);
    let b = Arc::new(b);
    let expected = (b.config().timeout, 2, 7);
    assert_eq!(timing(&Pbl::new(Arc::clone(&b), 7)), expected);
    assert_eq!(timing(&J2::new(Arc::clone(&b), 7)), expected);
    assert_eq!(timing(&instrument(Arc::clone(&b))), expected);
}

#[test]
fn a_devices_own_retries_replace_the_buss_in_every_family() {
    // The Bus retries twice; each device asks for none: one silent request, then a timeout.
    let timeout = Some(Duration::from_millis(5));
    let (b, t) = bus(silent_then_reply(), 2);
    let p = Pbl::new(Arc::new(b), 7).with_timing(timeout, Some(0));
    assert_eq!(p.station().retries(), 0);
    assert_eq!(p.station().timeout(), Duration::from_millis(5));
    assert!(matches!(p.read_parameter(50), Err(Error::Timeout { .. })));
    assert_eq!(sent(&t).len(), 1);

    let (b, t) = bus(silent_then_reply(), 2);
    let j = J2::new(Arc::new(b), 7).with_timing(timeout, Some(0));
    assert!(matches!(j.get("PV"), Err(Error::Timeout { .. })));
    assert_eq!(sent(&t).len(), 1);

    let (b, t) = bus(silent_then_reply(), 2);
    let i = instrument(Arc::new(b)).with_timing(timeout, Some(0));
    assert!(matches!(
        i.read_word(Table::Holding, 0),
        Err(Error::Timeout { .. })
    ));
    assert_eq!(sent(&t).len(), 1);

    // With three retries of its own (the Bus has two), the fourth request is answered.
    let (b, t) = bus(silent_then_reply(), 2);
    let i = instrument(Arc::new(b)).with_timing(timeout, Some(3));
    assert_eq!(i.read_word(Table::Holding, 0).ok(), Some(42));
    assert_eq!(sent(&t).len(), 4);
}

#[test]
fn the_drive_stands_on_the_station_too() {
    let (b, _) = bus(vec![], 2);
    let b = Arc::new(b);
    let drive = Drive::new(Arc::clone(&b), 7, Family::Bld, true);
    assert_eq!(timing(&drive), (b.config().timeout, 2, 7));
    assert!(Arc::ptr_eq(drive.bus(), &b));

    // Its own retries replace the Bus's: one silent request, then a timeout.
    let timeout = Some(Duration::from_millis(5));
    let (b, t) = bus(silent_then_reply(), 2);
    let d = Drive::new(Arc::new(b), 7, Family::C20, false).with_timing(timeout, Some(0));
    assert_eq!(d.station().timeout(), Duration::from_millis(5));
    assert!(!d.station().opts().write_ack && !d.write_ack());
    assert!(matches!(d.get("speed"), Err(Error::Timeout { .. })));
    assert_eq!(sent(&t).len(), 1);
}

/// A check that refuses every request, counting how often it was asked.
#[derive(Debug, Default)]
struct Refuse(std::sync::atomic::AtomicU32);

impl benchbus::device::Vouch for Refuse {
    fn vouch(&self, unit: u8) -> benchbus::Result<()> {
        self.0.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Err(Error::Unvouched {
            unit,
            reason: "not this kind of device".into(),
        })
    }
}

#[test]
fn a_unit_its_vouch_refuses_gets_nothing_but_an_urgent_stop() {
    let (b, t) = bus(vec![Act::Silent], 0);
    let refuse = Arc::new(Refuse::default());
    let d = Drive::new(Arc::new(b), 7, Family::Bld, true)
        .with_vouch(Arc::clone(&refuse) as Arc<dyn benchbus::device::Vouch>);
    // Bad input is refused before the check is asked.
    assert!(matches!(
        d.set("speed_setpoint", 1e9),
        Err(Error::InvalidArgument(_))
    ));
    assert_eq!(refuse.0.load(std::sync::atomic::Ordering::SeqCst), 0);
    // Reads and writes: refused unsent.
    assert!(matches!(
        d.get("speed"),
        Err(Error::Unvouched { unit: 7, .. })
    ));
    assert!(matches!(
        d.set("speed_setpoint", 100.0),
        Err(Error::Unvouched { .. })
    ));
    assert!(matches!(
        d.stop_on_exit(false),
        Err(Error::Unvouched { .. })
    ));
    assert_eq!(refuse.0.load(std::sync::atomic::Ordering::SeqCst), 3);
    assert!(sent(&t).is_empty());
    // The urgent stop (leaving on an error) goes without the check: once, the stop.
    assert!(d.stop_on_exit(true).is_err()); // the script is silent
    assert_eq!(sent(&t).len(), 1);
    assert_eq!(&sent(&t)[0][..6], &[7, 0x06, 0x20, 0x00, 0x00, 0x05]);
}

/// Reads `name` through the one interface every family with a table has.
fn by_name(device: &impl Tabled, name: &str) -> benchbus::Result<(u16, f64)> {
    Ok((device.row(name)?.register.address, device.get(name)?))
}

#[test]
fn every_family_with_a_table_reads_and_refuses_by_name_the_same_way() {
    // The raw word 0xFFF6 is each row's own value: 65526 rpm of a setpoint in whole rpm,
    // -1.0 of the J2's SV in signed tenths.
    let (b, t) = bus(vec![words(7, &[0xFFF6])], 0);
    let drive = Drive::new(Arc::new(b), 7, Family::Bld, true);
    assert_eq!(
        by_name(&drive, "speed_setpoint").ok(),
        Some((0x2001, 65526.0))
    );
    assert_eq!(sent(&t).len(), 1);

    let (b, _) = bus(vec![words(7, &[0xFFF6])], 0);
    let j2 = J2::new(Arc::new(b), 7);
    assert_eq!(by_name(&j2, "sv").ok(), Some((0x0006, -1.0)));

    let (b, t) = bus(vec![words(7, &[4])], 0);
    let pbl = Pbl::new(Arc::new(b), 7);
    assert_eq!(by_name(&pbl, "pole_pairs").ok(), Some((205, 4.0)));
    assert_eq!(sent(&t).len(), 1);

    // A name the table lacks and a value out of range: refused, nothing sent.
    let (b, t) = bus(vec![], 0);
    let pbl = Pbl::new(Arc::new(b), 7);
    assert!(matches!(
        Tabled::get(&pbl, "nope"),
        Err(Error::InvalidArgument(_))
    ));
    assert!(matches!(
        Tabled::set(&pbl, "speed", 1.0),
        Err(Error::InvalidArgument(_))
    ));
    let (b2, t2) = bus(vec![], 0);
    let drive = Drive::new(Arc::new(b2), 7, Family::Bld, true);
    assert!(matches!(
        Tabled::set(&drive, "pole_pairs", 21.0),
        Err(Error::InvalidArgument(_))
    ));
    assert!(sent(&t).is_empty() && sent(&t2).is_empty());
}
