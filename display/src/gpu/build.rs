//! The pieces every GPU driver builds its passes from: uniform buffers and
//! their bindings, a render pipeline into a color target with a depth test,
//! and a pass that clears both.

use super::target::DEPTH_FORMAT;

/// A uniform buffer of `size` bytes, written each frame.
pub fn uniform_buffer(device: &wgpu::Device, label: &str, size: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A uniform buffer's entry at `binding` of a bind group layout.
pub fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// What a pipeline draws with.
#[derive(Debug)]
pub struct PipelineSpec<'a> {
    /// Its name in GPU tools and errors.
    pub label: &'a str,
    /// The shader module, with entry points `vs` and `fs`.
    pub module: &'a wgpu::ShaderModule,
    /// The bind group layouts, in group order.
    pub groups: &'a [Option<&'a wgpu::BindGroupLayout>],
    /// The one vertex buffer's layout.
    pub buffer: wgpu::VertexBufferLayout<'a>,
    /// The depth test (writing depth).
    pub depth_compare: wgpu::CompareFunction,
    /// The color target's format.
    pub format: wgpu::TextureFormat,
}

/// A triangle pipeline as `spec` says, with no culling and no blending.
pub fn pipeline(device: &wgpu::Device, spec: &PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(spec.label),
        bind_group_layouts: spec.groups,
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: spec.module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[Some(spec.buffer.clone())],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(spec.depth_compare),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: spec.module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(spec.format.into())],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Begins a pass that clears `color` to `clear` and `depth` to
/// `depth_clear`, keeping the color and discarding the depth.
pub fn clearing_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    color: &wgpu::TextureView,
    clear: wgpu::Color,
    depth: &wgpu::TextureView,
    depth_clear: f32,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(clear),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(depth_clear),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
