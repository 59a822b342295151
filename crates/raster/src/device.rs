//! Choosing the compute backend at run time from a command-line name.
//!
//! Every program of the project takes `--backend flex|ndarray|wgpu`; this module is the one place
//! that turns that name into a [`Device`], so error messages and defaults stay consistent.

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use burn::tensor::Device;

/// A compute backend the project is built and tested on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Backend {
    /// burn-flex: the pure-Rust CPU backend (default; fastest on CPU).
    #[default]
    Flex,
    /// burn-ndarray: the older CPU backend, deprecated upstream but kept and tested.
    Ndarray,
    /// burn-wgpu: any GPU through wgpu (Vulkan, Metal, DX12), or Mesa lavapipe on a CPU-only
    /// machine. Needs the crate feature `wgpu`.
    Wgpu,
}

/// Why a backend name could not be turned into a usable device.
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// The name is not one of `flex`, `ndarray`, `wgpu`.
    #[error("unknown backend `{0}`: expected one of flex, ndarray, wgpu")]
    Unknown(String),
    /// The program was built without the backend's feature (`ndarray` or `wgpu`).
    #[error("backend `{0}` is not compiled in: rebuild with `--features {0}`")]
    NotCompiled(Backend),
    /// wgpu found no adapter or could not open a device.
    #[error(
        "backend `wgpu` is unavailable: {0} (on a machine without a GPU, install Mesa's Vulkan \
         drivers, e.g. `apt-get install mesa-vulkan-drivers`)"
    )]
    Unavailable(Arc<dyn std::error::Error + Send + Sync>),
}

impl Backend {
    /// All backends, in the order the project documents them.
    pub const ALL: [Backend; 3] = [Backend::Flex, Backend::Ndarray, Backend::Wgpu];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Flex => "flex",
            Backend::Ndarray => "ndarray",
            Backend::Wgpu => "wgpu",
        }
    }

    /// The device for this backend, without autodiff (inference, exact evaluation).
    ///
    /// wgpu is initialized once per process and its device reused, so calling this repeatedly
    /// is cheap and never fails after a first success.
    pub fn device(self) -> Result<Device, BackendError> {
        match self {
            Backend::Flex => Ok(Device::flex()),
            Backend::Ndarray => ndarray_device(),
            Backend::Wgpu => wgpu_device(),
        }
    }

    /// The device for this backend with autodiff enabled (training; needs the `autodiff` feature).
    #[cfg(feature = "autodiff")]
    pub fn autodiff_device(self) -> Result<Device, BackendError> {
        Ok(self.device()?.autodiff())
    }
}

#[cfg(feature = "wgpu")]
fn wgpu_device() -> Result<Device, BackendError> {
    use std::sync::OnceLock;
    // The first outcome is kept, failure included: shared, as errors are not Clone.
    static DEVICE: OnceLock<Result<Device, Arc<dyn std::error::Error + Send + Sync>>> = OnceLock::new();
    DEVICE
        .get_or_init(|| Device::wgpu_options().init().map_err(|err| Arc::new(err) as _))
        .clone()
        .map_err(BackendError::Unavailable)
}

#[cfg(not(feature = "wgpu"))]
fn wgpu_device() -> Result<Device, BackendError> {
    Err(BackendError::NotCompiled(Backend::Wgpu))
}

#[cfg(feature = "ndarray")]
fn ndarray_device() -> Result<Device, BackendError> {
    #[allow(deprecated)]
    Ok(Device::ndarray())
}

#[cfg(not(feature = "ndarray"))]
fn ndarray_device() -> Result<Device, BackendError> {
    Err(BackendError::NotCompiled(Backend::Ndarray))
}

impl FromStr for Backend {
    type Err = BackendError;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Backend::ALL
            .into_iter()
            .find(|backend| backend.name().eq_ignore_ascii_case(name.trim()))
            .ok_or_else(|| BackendError::Unknown(name.to_string()))
    }
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for backend in Backend::ALL {
            assert_eq!(backend.name().parse::<Backend>().unwrap(), backend);
        }
        assert_eq!(" WGPU ".parse::<Backend>().unwrap(), Backend::Wgpu);
    }

    #[test]
    fn unknown_name_is_a_clear_error() {
        let err = "cuda".parse::<Backend>().unwrap_err();
        assert_eq!(err.to_string(), "unknown backend `cuda`: expected one of flex, ndarray, wgpu");
    }

    #[cfg(all(feature = "ndarray", feature = "autodiff"))]
    #[test]
    fn cpu_backends_always_available() {
        assert!(Backend::Flex.device().is_ok());
        assert!(Backend::Ndarray.autodiff_device().unwrap().is_autodiff());
    }

    #[cfg(not(feature = "wgpu"))]
    #[test]
    fn wgpu_without_feature_says_how_to_enable_it() {
        let err = Backend::Wgpu.device().unwrap_err();
        assert!(err.to_string().contains("--features wgpu"), "{err}");
    }
}
