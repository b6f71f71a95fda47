//! The serial ports the system knows, with what it knows of each: for a USB adapter its
//! vendor and product ids, the names and serial number it reports, and the chip family
//! those ids belong to ([`CHIPS`]), so that a user finds `/dev/ttyUSB0` without guessing.
//!
//! On Linux the ports are read from sysfs (`/sys/class/tty/<name>/device`, then up the
//! device tree to the USB device's `idVendor`, `idProduct`, `manufacturer`, `product` and
//! `serial`), under a root that `list_ports_in` (Linux only) takes as a parameter; elsewhere
//! [`list_ports`] asks the serialport crate.

use std::io;
#[cfg(target_os = "linux")]
use std::path::Path;

/// USB-to-serial chip families by vendor id, and product id where one vendor makes several:
/// `(vendor, product or None for any, family)`, the first match wins.
pub const CHIPS: &[(u16, Option<u16>, &str)] = &[
    (0x0403, None, "FTDI"),
    (0x1A86, Some(0x7523), "CH340"),
    (0x1A86, Some(0x5523), "CH341"),
    (0x1A86, None, "CH34x (WCH)"),
    (0x10C4, None, "CP210x"),
    (0x067B, None, "PL2303"),
];

/// The chip family of a USB adapter from its vendor and product ids, if [`CHIPS`] has it.
pub fn chip(vid: u16, pid: u16) -> Option<&'static str> {
    CHIPS
        .iter()
        .find(|(v, p, _)| *v == vid && p.is_none_or(|p| p == pid))
        .map(|(_, _, name)| *name)
}

/// What the system reports of a USB serial adapter.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct UsbInfo {
    /// Vendor id.
    pub vid: u16,
    /// Product id.
    pub pid: u16,
    /// The manufacturer string, if the adapter reports one.
    pub manufacturer: Option<String>,
    /// The product string, if the adapter reports one.
    pub product: Option<String>,
    /// The serial number, if the adapter reports one.
    pub serial_number: Option<String>,
}

impl UsbInfo {
    /// The chip family, from [`CHIPS`].
    pub fn chip(&self) -> Option<&'static str> {
        chip(self.vid, self.pid)
    }
}

/// A serial port: its path and what the system knows of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PortInfo {
    /// The path to open (`/dev/ttyUSB0`).
    pub path: String,
    /// The kernel driver behind it (`ftdi_sio`, `ch341-uart`, `serial8250`), where known.
    pub driver: Option<String>,
    /// The USB adapter it belongs to, or None (a board's own UART, a PCI card...).
    pub usb: Option<UsbInfo>,
}

/// The serial ports of this system, sorted by path.
///
/// # Errors
/// The system's error if the list cannot be read (a missing `/sys/class/tty` is an empty
/// list, not an error).
pub fn list_ports() -> io::Result<Vec<PortInfo>> {
    #[cfg(target_os = "linux")]
    {
        list_ports_in(Path::new("/sys"))
    }
    #[cfg(not(target_os = "linux"))]
    {
        from_serialport()
    }
}

#[cfg(not(target_os = "linux"))]
fn from_serialport() -> io::Result<Vec<PortInfo>> {
    let ports = serialport::available_ports()
        .map_err(|e| io::Error::other(format!("cannot list the serial ports: {e}")))?;
    let mut out: Vec<PortInfo> = ports
        .into_iter()
        .map(|p| PortInfo {
            path: p.port_name,
            driver: None,
            usb: match p.port_type {
                serialport::SerialPortType::UsbPort(u) => Some(UsbInfo {
                    vid: u.vid,
                    pid: u.pid,
                    manufacturer: u.manufacturer,
                    product: u.product,
                    serial_number: u.serial_number,
                }),
                _ => None,
            },
        })
        .collect();
    sort_by_path(&mut out);
    Ok(out)
}

/// Sorts ports by path, a number at its end by value: `COM2` before `COM10`, `/dev/ttyUSB2`
/// before `/dev/ttyUSB10`.
fn sort_by_path(ports: &mut [PortInfo]) {
    ports.sort_by(|a, b| path_key(&a.path).cmp(&path_key(&b.path)));
}

/// A path's sort key: the text before its trailing digits, then those digits by value (a
/// longer run of digits, leading zeros aside, is a larger number).
fn path_key(path: &str) -> (&str, usize, &str) {
    let head = path.trim_end_matches(|c: char| c.is_ascii_digit());
    let digits = path.get(head.len()..).unwrap_or_default();
    let digits = digits.trim_start_matches('0');
    (head, digits.len(), digits)
}

/// How many directories up from a tty's device the USB device may be (the tty's own
/// directory, the usb-serial port, the interface, the device).
#[cfg(target_os = "linux")]
const USB_DEPTH: usize = 4;

/// The serial ports under a sysfs tree rooted at `sysfs` (`/sys` on a running system),
/// sorted by path: each `class/tty/<name>` with a `device`, as `/dev/<name>`. A tty with no
/// device is virtual (a console, a pseudo-terminal); one whose `type` reads 0 is a UART the
/// driver reserved that is not there (most of `ttyS0..31`).
///
/// # Errors
/// The system's error if `class/tty` exists but cannot be read.
#[cfg(target_os = "linux")]
pub fn list_ports_in(sysfs: &Path) -> io::Result<Vec<PortInfo>> {
    let class = sysfs.join("class").join("tty");
    let entries = match std::fs::read_dir(&class) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e),
    };
    let mut out = Vec::new();
    for entry in entries {
        let tty = entry?.path();
        let Some(name) = tty.file_name().and_then(|n| n.to_str()).map(str::to_owned) else {
            continue;
        };
        let Ok(device) = std::fs::canonicalize(tty.join("device")) else {
            continue;
        };
        if read_text(&tty.join("type")).as_deref() == Some("0") {
            continue;
        }
        out.push(PortInfo {
            path: format!("/dev/{name}"),
            driver: driver_of(&device),
            usb: usb_above(&device),
        });
    }
    sort_by_path(&mut out);
    Ok(out)
}

/// The driver of `device`: the first one at or above it that is not the kernel's generic
/// serial-base layer (Linux 6.5+ puts a `port` and a `ctrl` device between a UART and its
/// driver).
#[cfg(target_os = "linux")]
fn driver_of(device: &Path) -> Option<String> {
    device
        .ancestors()
        .take(USB_DEPTH)
        .filter_map(|d| std::fs::read_link(d.join("driver")).ok())
        .find(|link| !link.components().any(|c| c.as_os_str() == "serial-base"))
        .and_then(|link| link.file_name().and_then(|n| n.to_str()).map(str::to_owned))
}

/// The USB device at or above `device`, read from the first directory with an `idVendor`.
#[cfg(target_os = "linux")]
fn usb_above(device: &Path) -> Option<UsbInfo> {
    let dir = device
        .ancestors()
        .take(USB_DEPTH)
        .find(|d| d.join("idVendor").is_file())?;
    let id = |file: &str| read_text(&dir.join(file)).and_then(|t| u16::from_str_radix(&t, 16).ok());
    Some(UsbInfo {
        vid: id("idVendor")?,
        pid: id("idProduct")?,
        manufacturer: read_text(&dir.join("manufacturer")),
        product: read_text(&dir.join("product")),
        serial_number: read_text(&dir.join("serial")),
    })
}

/// A sysfs attribute's text, trimmed; None if it is missing, unreadable or empty.
#[cfg(target_os = "linux")]
fn read_text(path: &Path) -> Option<String> {
    let text = std::fs::read_to_string(path).ok()?;
    let text = text.trim();
    (!text.is_empty()).then(|| text.to_owned())
}

#[cfg(test)]
mod sort_tests {
    use super::*;

    #[test]
    fn ports_sort_by_the_number_at_the_end_of_their_path() {
        let mut ports: Vec<PortInfo> = [
            "COM10",
            "COM2",
            "COM1",
            "/dev/ttyUSB10",
            "/dev/ttyUSB2",
            "/dev/ttyS0",
            "COM",
            "COM03",
        ]
        .into_iter()
        .map(|path| PortInfo {
            path: path.into(),
            driver: None,
            usb: None,
        })
        .collect();
        sort_by_path(&mut ports);
        let paths: Vec<&str> = ports.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "/dev/ttyS0",
                "/dev/ttyUSB2",
                "/dev/ttyUSB10",
                "COM",
                "COM1",
                "COM2",
                "COM03",
                "COM10"
            ]
        );
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;
    use std::path::PathBuf;

    /// A sysfs tree in a fresh tmp dir (removed on drop).
    pub struct FakeSysfs(PathBuf);

    impl FakeSysfs {
        fn new(tag: &str) -> FakeSysfs {
            let root = std::env::temp_dir().join(format!(
                "benchbus-sysfs-{tag}-{}-{:?}",
                std::process::id(),
                std::thread::current().id()
            ));
            let _ = std::fs::remove_dir_all(&root);
            std::fs::create_dir_all(root.join("class/tty")).unwrap();
            FakeSysfs(root)
        }

        fn write(&self, rel: &str, text: &str) {
            let path = self.0.join(rel);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }

        fn link(&self, rel: &str, to: &str) {
            let path = self.0.join(rel);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::create_dir_all(self.0.join(to)).unwrap();
            symlink(self.0.join(to), path).unwrap();
        }

        /// A tty whose device is `device` (a dir under the root), driven by `driver`.
        fn tty(&self, name: &str, device: &str, driver: &str) {
            std::fs::create_dir_all(self.0.join("class/tty").join(name)).unwrap();
            self.link(&format!("class/tty/{name}/device"), device);
            self.link(
                &format!("{device}/driver"),
                &format!("bus/drivers/{driver}"),
            );
        }

        fn usb(&self, dir: &str, vid: &str, pid: &str, strings: &[(&str, &str)]) {
            self.write(&format!("{dir}/idVendor"), &format!("{vid}\n"));
            self.write(&format!("{dir}/idProduct"), &format!("{pid}\n"));
            for (file, text) in strings {
                self.write(&format!("{dir}/{file}"), &format!("{text}\n"));
            }
        }
    }

    impl Drop for FakeSysfs {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn usb_adapters_and_a_board_uart_are_listed_with_what_sysfs_knows() {
        let sys = FakeSysfs::new("three");
        let ftdi = "devices/pci0/usb1/1-1";
        sys.usb(
            ftdi,
            "0403",
            "6001",
            &[
                ("manufacturer", "FTDI"),
                ("product", "FT232R USB UART"),
                ("serial", "A50285BI"),
            ],
        );
        sys.tty("ttyUSB0", &format!("{ftdi}/1-1:1.0/ttyUSB0"), "ftdi_sio");
        let ch340 = "devices/pci0/usb1/1-2";
        sys.usb(ch340, "1a86", "7523", &[("product", "USB Serial")]);
        sys.tty("ttyUSB1", &format!("{ch340}/1-2:1.0/ttyUSB1"), "ch341-uart");
        sys.tty("ttyAMA0", "devices/platform/fe201000.serial", "uart-pl011");
        // a PC's UART behind the serial-base layer (port, ctrl), driven by the pnp "serial"
        let uart = "devices/pnp0/00:00";
        sys.link(&format!("{uart}/driver"), "bus/pnp/drivers/serial");
        sys.link(
            &format!("{uart}/00:00:0/driver"),
            "bus/serial-base/drivers/ctrl",
        );
        sys.tty("ttyS0", &format!("{uart}/00:00:0/00:00:0.0"), "port");
        std::fs::remove_file(sys.0.join(format!("{uart}/00:00:0/00:00:0.0/driver"))).unwrap();
        sys.link(
            &format!("{uart}/00:00:0/00:00:0.0/driver"),
            "bus/serial-base/drivers/port",
        );
        sys.write("class/tty/ttyS0/type", "4\n");
        sys.tty("ttyS1", "devices/platform/serial8250", "serial8250");
        sys.write("class/tty/ttyS1/type", "0\n"); // reserved, not there
        std::fs::create_dir_all(sys.0.join("class/tty/tty0")).unwrap(); // virtual: no device

        let ports = list_ports_in(&sys.0).unwrap();
        let paths: Vec<&str> = ports.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(
            paths,
            ["/dev/ttyAMA0", "/dev/ttyS0", "/dev/ttyUSB0", "/dev/ttyUSB1"]
        );
        assert_eq!(ports[0].usb, None);
        assert_eq!(ports[0].driver.as_deref(), Some("uart-pl011"));
        assert_eq!(
            (ports[1].usb.clone(), ports[1].driver.as_deref()),
            (None, Some("serial"))
        );
        let ports = &ports[1..];
        let usb0 = ports[1].usb.clone().unwrap();
        assert_eq!(
            (usb0.vid, usb0.pid, usb0.chip()),
            (0x0403, 0x6001, Some("FTDI"))
        );
        assert_eq!(usb0.product.as_deref(), Some("FT232R USB UART"));
        assert_eq!(usb0.serial_number.as_deref(), Some("A50285BI"));
        assert_eq!(ports[1].driver.as_deref(), Some("ftdi_sio"));
        let usb1 = ports[2].usb.clone().unwrap();
        assert_eq!(
            (usb1.chip(), usb1.manufacturer, usb1.serial_number),
            (Some("CH340"), None, None)
        );
    }

    #[test]
    fn no_tty_class_is_an_empty_list() {
        let sys = FakeSysfs::new("empty");
        std::fs::remove_dir_all(sys.0.join("class")).unwrap();
        assert_eq!(list_ports_in(&sys.0).unwrap(), []);
        assert_eq!(list_ports_in(Path::new("/nonexistent/sysfs")).unwrap(), []);
    }

    #[test]
    fn a_garbled_usb_id_is_no_usb_info_not_a_panic() {
        let sys = FakeSysfs::new("garbled");
        sys.usb("devices/usb1/1-3", "zz", "7523", &[]);
        sys.tty("ttyACM0", "devices/usb1/1-3/1-3:1.0", "cdc_acm");
        let ports = list_ports_in(&sys.0).unwrap();
        assert_eq!(ports.len(), 1);
        assert_eq!(ports[0].usb, None);
    }

    #[test]
    fn chips_by_vendor_and_product() {
        assert_eq!(chip(0x1A86, 0x5523), Some("CH341"));
        assert_eq!(chip(0x1A86, 0x55D4), Some("CH34x (WCH)"));
        assert_eq!(chip(0x10C4, 0xEA60), Some("CP210x"));
        assert_eq!(chip(0x067B, 0x2303), Some("PL2303"));
        assert_eq!(chip(0x2341, 0x0043), None);
    }
}
