//! An ATI Net F/T six-axis force/torque sensor over UDP (its RDT protocol), and an emulator.
//!
//! # Layers
//!
//! - [`wire`]: the RDT request (8 bytes) and record (36 bytes), big-endian; the status word;
//!   the calibration (counts per force, counts per torque); sequence gaps.
//! - [`sensor`]: the driver: [`NetFt`] owns the UDP socket in its own I/O thread (start and stop
//!   streaming, software bias, loss and timeout detection, counters) and publishes each record
//!   into lock-free latest-value cells; [`NetFtReader`] is the control thread's side, a
//!   `hal::ForceSensor` with typed errors ([`NetFtError`]).
//! - [`emulator`]: [`emulator::NetFtEmulator`], the box on a loopback port at up to 7 kHz,
//!   loaded by a contact model ([`emulator::ProbedContact`]: the environment shapes probed at a
//!   tool pose), with injectable faults ([`emulator::Faults`]).
//!
//! # The protocol, and what this driver assumes
//!
//! From ATI's Net F/T manual (9620-05-NET FT), "Raw Data Transfer": the host sends an 8-byte
//! request to UDP port 49152: `uint16 command_header = 0x1234`, `uint16 command` (0 stop, 2
//! start real-time streaming, 3 start buffered, 4 start multi-unit, `0x42` set software bias),
//! `uint32 sample_count` (0: stream until stopped). The box answers with RDT records of 36
//! bytes: `uint32 rdt_sequence`, `uint32 ft_sequence`, `uint32 status`, then `int32` Fx, Fy,
//! Fz, Tx, Ty, Tz in counts. Assumptions, stated here because the driver depends on them:
//!
//! - **Real-time streaming only** (command 2): one record per datagram. Buffered and
//!   multi-unit streaming are encoded and decoded as requests but the driver does not use them.
//! - **Units.** Forces are divided by counts per force and torques by counts per torque, as
//!   configured (the box's `cfgcpf` and `cfgcpt`, often 1 000 000); the box must be set to
//!   newtons and newton-metres.
//! - **Status.** 0 is healthy; bit 31 means an error. Bits 30 (force/torque out of range) and
//!   27 (gage out of range) are read as saturation, after ATI's published status-code table;
//!   any other bit with bit 31 is reported as a device error with the whole word.
//! - **Loss.** `rdt_sequence` increases by one per record and wraps; a jump is records lost
//!   (counted); a repeated or older number is refused (counted). A gap longer than `max_gap`
//!   records is a fault, held for the timeout so that a slower reader sees it.
//! - **Sign.** The reading is taken as the wrench the robot exerts on the world in the sensor
//!   frame, the project's wrist-sensor convention (`sim::force_sensor`). A transducer mounted
//!   the other way round is described by its `mount` rotation.
//! - **Bias.** The box's software bias (command `0x42`) is sent from the I/O thread, never from
//!   the control thread; `ForceSensor::tare` on the reader is a host-side tare.
//! - **One client.** The box streams to the host that last asked it to; a second client
//!   (`penelope netft monitor` while a loop reads the box) takes the stream away, and the first
//!   one's timeout then asks for it back. The emulator does the same.
//! - **Transport.** UDP, so nothing is retransmitted: a record lost is lost, the next one
//!   replaces it. The I/O thread re-sends the start request after a silence of one timeout (a
//!   rebooted box, or a first request lost).

pub mod emulator;
pub mod sensor;
pub mod wire;

pub use sensor::{
    AddressError, MAX_READERS, NetFt, NetFtConfig, NetFtCounters, NetFtError, NetFtReader,
    NetFtSample, SampleFault, parse_address,
};
pub use wire::{Calibration, Command, RDT_PORT, RdtError, Record, Request, Status};
