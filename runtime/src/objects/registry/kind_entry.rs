//! A catalog entry: what the registry knows of a kind (its name, summary, configuration and
//! maker), and what a maker is given. Below the catalog and the kinds' modules, which both use it.

use std::path::PathBuf;

use penelope_protocol::proto::{Class, KindInfo};

use super::KindState;
use crate::objects::config::describe::Described;
use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;

/// What a kind's maker is given.
pub(crate) struct MakeArgs<'a> {
    /// The kind made.
    pub kind: Kind,
    /// Its configuration text (`""`: every default).
    pub config: &'a str,
    /// The directories a `robot/urdf`'s file may be read from ([`crate::objects::files`]).
    pub robot_files: &'a [PathBuf],
}

/// Makes a kind's object from its configuration (checked there; nothing opened yet).
pub(crate) type Maker = fn(&MakeArgs<'_>) -> Result<KindState, ObjectError>;

/// One registered kind.
#[derive(Clone, Copy)]
pub struct KindEntry {
    /// The kind: its name, `class/kind`.
    pub kind: Kind,
    /// One line on what it is.
    pub summary: &'static str,
    /// Its configuration.
    pub config: Described,
    /// Makes its object.
    pub(crate) make: Maker,
    /// A real device: it moves with real time, so a creator on the simulated clock refuses it.
    pub real_device: bool,
}

impl KindEntry {
    /// The entry of `kind`, summarised, described by `config`, made by `make`.
    pub(crate) const fn new(
        kind: Kind,
        summary: &'static str,
        config: Described,
        make: Maker,
    ) -> KindEntry {
        KindEntry {
            kind,
            summary,
            config,
            make,
            real_device: false,
        }
    }

    /// The same entry, for a real device ([`KindEntry::real_device`]).
    pub(crate) const fn as_real_device(mut self) -> KindEntry {
        self.real_device = true;
        self
    }

    /// `class/kind`.
    pub fn name(&self) -> &'static str {
        self.kind.as_str()
    }

    /// Its class: the name's prefix.
    pub fn class(&self) -> Class {
        self.kind.class()
    }

    /// What `kinds` lists for it.
    pub fn info(&self) -> KindInfo {
        KindInfo {
            kind: self.name().to_string(),
            class: self.class(),
            summary: self.summary.to_string(),
            config: (self.config.keys)(self.name()).trim().to_string(),
        }
    }
}
