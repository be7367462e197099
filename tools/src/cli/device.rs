//! A crowd of a model's characters on one Vulkan device: the arguments of `bench` and
//! `profile`.

use rrskin::vk::DeviceChoice;
use rrskin::Model;
use std::path::PathBuf;

use super::at_least_one;

/// A crowd of a model's characters run for some frames on one Vulkan device.
#[derive(clap::Args)]
pub struct RunArgs {
    pub model: PathBuf,
    #[arg(long, default_value_t = 256, value_parser = at_least_one)]
    pub characters: usize,
    /// Frames measured (after the warm-up).
    #[arg(long, default_value_t = 20, value_parser = at_least_one)]
    pub frames: usize,
    /// Use the first Vulkan device whose name contains this text.
    #[arg(long)]
    pub device: Option<String>,
    /// The device's peak memory bandwidth in GB/s (e.g. 4800 for an H200): `bench` then reports
    /// the fraction of the bandwidth bound each frame reaches (the least bytes a frame moves,
    /// `run::traffic`, over this, over the frame's time).
    #[arg(long)]
    pub bandwidth: Option<f64>,
    #[arg(long)]
    pub json: bool,
}

impl RunArgs {
    /// The model, and the device to run it on.
    pub fn load(&self) -> Result<(Model, DeviceChoice), Box<dyn std::error::Error>> {
        let choice = self
            .device
            .clone()
            .map_or(DeviceChoice::Auto, DeviceChoice::NameContains);
        Ok((Model::load(&self.model)?, choice))
    }
}
