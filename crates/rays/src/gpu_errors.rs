//! What wgpu refuses, as an error to return rather than a panic of its default handler.
//!
//! A validation error scope answers at once on a native device; a browser's WebGPU answers
//! only asynchronously, and a page cannot block on it. There the scope is not pushed, and
//! what the device refuses reaches its uncaptured-error handler (the browser's console).

/// A validation error scope around the work between [`Self::push`] and [`Self::pop`].
pub struct ValidationScope {
    #[cfg(not(target_arch = "wasm32"))]
    scope: wgpu::ErrorScopeGuard,
}

impl ValidationScope {
    pub fn push(device: &wgpu::Device) -> ValidationScope {
        #[cfg(not(target_arch = "wasm32"))]
        return ValidationScope { scope: device.push_error_scope(wgpu::ErrorFilter::Validation) };
        #[cfg(target_arch = "wasm32")]
        {
            let _ = device;
            ValidationScope {}
        }
    }

    /// The first validation error since [`Self::push`], if any (always none on the web).
    pub fn pop(self) -> Option<wgpu::Error> {
        #[cfg(not(target_arch = "wasm32"))]
        return pollster::block_on(self.scope.pop());
        #[cfg(target_arch = "wasm32")]
        None
    }
}
