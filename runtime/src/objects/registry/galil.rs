//! Opening a Galil board when it is configured.

use crate::objects::error::ObjectError;
use crate::objects::registry::GalilConfig;
use penelope_drivers::galil::board::LinkFactory;
use penelope_drivers::galil::{GalilBoard, GalilBoardConfig, Link, TcpLink};
use std::time::Duration;

/// Opens a Galil board.
pub(super) fn open_galil(cfg: &GalilConfig) -> Result<GalilBoard, ObjectError> {
    let volts = cfg.volts();
    let path = cfg.device.clone().unwrap_or_else(|| "tcp".into());
    let mut board_cfg = GalilBoardConfig::new(path.clone(), cfg.axes as usize, &volts);
    board_cfg.serial.baud = cfg.baud;
    board_cfg.watchdog = (cfg.watchdog_ms > 0).then(|| Duration::from_millis(cfg.watchdog_ms));
    board_cfg.command_timeout =
        (cfg.command_timeout_ms > 0).then(|| Duration::from_millis(cfg.command_timeout_ms));
    let result = match &cfg.address {
        Some(address) => {
            let address = address.clone();
            let timeout = Duration::from_millis(cfg.connect_timeout_ms);
            let factory: LinkFactory = Box::new(move || {
                use std::net::ToSocketAddrs;
                let addr = address
                    .to_socket_addrs()
                    .map_err(|e| penelope_drivers::galil::GalilError::Io(e.kind()))?
                    .next()
                    .ok_or(penelope_drivers::galil::GalilError::Closed)?;
                let stream = std::net::TcpStream::connect_timeout(&addr, timeout)
                    .map_err(|e| penelope_drivers::galil::GalilError::Io(e.kind()))?;
                TcpLink::new(stream).map(|l| Box::new(l) as Box<dyn Link + Send>)
            });
            GalilBoard::with_link_factory(board_cfg, factory)
        }
        None => GalilBoard::open(board_cfg),
    };
    let place = cfg
        .address
        .as_deref()
        .or(cfg.device.as_deref())
        .unwrap_or("?")
        .to_string();
    let board = result.map_err(|e| ObjectError::device(format!("galil board at {place}"), e))?;
    // Configured means ready: wait for the I/O thread's first exchange, so the encoders can be
    // read as soon as `configure` returns.
    let deadline = std::time::Instant::now() + FIRST_EXCHANGE_TIMEOUT;
    while board.cycles() == 0 {
        if board.is_faulted() || std::time::Instant::now() >= deadline {
            return Err(ObjectError::DeviceRefused(format!(
                "galil board at {place}: no answer within {} ms",
                FIRST_EXCHANGE_TIMEOUT.as_millis()
            )));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Ok(board)
}

/// How long `configure` of a Galil board waits for the first exchange with the controller.
const FIRST_EXCHANGE_TIMEOUT: Duration = Duration::from_secs(2);
