//! The wgpu device: headless (the command line, tests, benchmarks) or the caller's (a window), with
//! the adapter's limits and timestamp queries where it has them.

/// What can go wrong on the GPU side, named for the user.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter could be found.
    #[error(
        "no GPU adapter ({0}); without a GPU install Mesa's lavapipe (scripts/install-deps) and set WGPU_BACKEND=vulkan"
    )]
    NoAdapter(String),
    /// The device could not be opened.
    #[error("cannot open the GPU device: {0}")]
    Device(String),
    /// A shader is missing or invalid.
    #[error("shader: {0}")]
    Shader(String),
    /// The GPU did not finish or a read-back failed.
    #[error("GPU read-back: {0}")]
    Readback(String),
    /// A pass was asked of targets that lack what it writes.
    #[error("{0}")]
    Targets(&'static str),
    /// A job larger than the device's limits allow (named with the limit).
    #[error("device limit: {0}")]
    Limit(String),
    /// An image could not be encoded as PNG.
    #[error("{}: cannot encode PNG", path.display())]
    Png {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// An image could not be written.
    #[error("{}: cannot write", path.display())]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The scene could not give what the GPU was to draw (a store, a layer).
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// A layer stack that the GPU cannot compose (too many layers, segments or octaves).
    #[error("layer stack: {0}")]
    Stack(String),
}

/// A wgpu device and queue, and what the adapter can do.
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter (name, backend, type).
    pub info: wgpu::AdapterInfo,
    /// Whether GPU pass times can be measured.
    pub timestamps: bool,
}

impl GpuContext {
    /// A device without a window: the best adapter the environment allows (`WGPU_BACKEND`,
    /// `WGPU_ADAPTER_NAME` select one, as in every wgpu program).
    pub fn headless() -> Result<GpuContext, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        GpuContext::from_adapter(&adapter)
    }

    /// A device on a given adapter, with the adapter's limits (large storage buffers) and
    /// timestamp queries where it has them.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext, GpuError> {
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("terrafuse"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        Ok(GpuContext {
            device,
            queue,
            info: adapter.get_info(),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
        })
    }

    /// "name (backend, type)".
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?})", self.info.name, self.info.backend, self.info.device_type)
    }
}
