//! The mesh driver's GPU side: vertex and index buffers, one pipeline.

use std::sync::Arc;

use super::MeshVertex;
use crate::gpu::build::{clearing_pass, pipeline, uniform_buffer, uniform_entry, PipelineSpec};
use crate::gpu::target::COLOR_FORMAT;
use crate::gpu::view::PROJECT_WGSL;
use crate::gpu::{GpuContext, GpuError, Target, TargetKind, ViewUniform};

/// Pipeline, buffers and target of a mesh driver.
#[derive(Debug)]
pub struct MeshPipeline {
    gpu: Arc<GpuContext>,
    pipeline: wgpu::RenderPipeline,
    bind: wgpu::BindGroup,
    view: wgpu::Buffer,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    target: Option<Target>,
}

impl MeshPipeline {
    /// The pipeline on `gpu`.
    pub fn new(gpu: Arc<GpuContext>) -> MeshPipeline {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mesh"),
            source: wgpu::ShaderSource::Wgsl(format!("{PROJECT_WGSL}\n{}", include_str!("mesh.wgsl")).into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mesh view"),
            entries: &[uniform_entry(0, wgpu::ShaderStages::VERTEX)],
        });
        let view = uniform_buffer(device, "mesh view", std::mem::size_of::<ViewUniform>());
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mesh view"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: view.as_entire_binding(),
            }],
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4];
        let pipeline = pipeline(
            device,
            &PipelineSpec {
                label: "mesh",
                module: &module,
                groups: &[Some(&layout)],
                buffer: wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<MeshVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                },
                depth_compare: wgpu::CompareFunction::Greater,
                format: COLOR_FORMAT,
            },
        );
        let vertices = buffer(device, 1 << 16, wgpu::BufferUsages::VERTEX);
        let indices = buffer(device, 1 << 16, wgpu::BufferUsages::INDEX);
        MeshPipeline {
            gpu,
            pipeline,
            bind,
            view,
            vertices,
            indices,
            target: None,
        }
    }

    /// A frame drawn is still on its way back from the GPU (a web page's).
    pub fn pending(&self) -> bool {
        self.target.as_ref().is_some_and(|t| t.reading())
    }

    /// Draws the triangles `indices` of `vertices` as `view` sees them into
    /// a `width` x `height` target and reads the frame back as RGBA floats.
    pub fn draw(
        &mut self,
        view: &ViewUniform,
        width: u32,
        height: u32,
        vertices: &[MeshVertex],
        indices: &[u32],
    ) -> Result<Vec<f32>, GpuError> {
        let gpu = Arc::clone(&self.gpu);
        let (device, queue) = (&gpu.device, &gpu.queue);
        // A web page's frame read back later: the one on its way comes first.
        if let Some(t) = self.target.as_ref().filter(|t| t.reading()) {
            return t.try_read(&gpu).unwrap_or(Err(GpuError::NotReady));
        }
        if self
            .target
            .as_ref()
            .is_none_or(|t| t.width != width || t.height != height)
        {
            self.target = Some(Target::new(&gpu, width, height, TargetKind::Color));
        }
        let vbytes = std::mem::size_of_val(vertices) as u64;
        if vbytes > self.vertices.size() {
            self.vertices = buffer(device, vbytes.next_power_of_two(), wgpu::BufferUsages::VERTEX);
        }
        let ibytes = std::mem::size_of_val(indices) as u64;
        if ibytes > self.indices.size() {
            self.indices = buffer(device, ibytes.next_power_of_two(), wgpu::BufferUsages::INDEX);
        }
        if !vertices.is_empty() {
            queue.write_buffer(&self.vertices, 0, bytemuck::cast_slice(vertices));
        }
        if !indices.is_empty() {
            queue.write_buffer(&self.indices, 0, bytemuck::cast_slice(indices));
        }
        queue.write_buffer(&self.view, 0, bytemuck::bytes_of(view));
        let Some(target) = self.target.as_ref() else {
            return Err(GpuError::Readback("no target".into()));
        };
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("mesh") });
        {
            let mut pass = clearing_pass(
                &mut encoder,
                "mesh",
                &target.color_view,
                wgpu::Color::TRANSPARENT,
                &target.depth_view,
                0.0,
            );
            if !indices.is_empty() {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind, &[]);
                pass.set_vertex_buffer(0, self.vertices.slice(..));
                pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..indices.len() as u32, 0, 0..1);
            }
        }
        target.copy_out(&mut encoder);
        queue.submit([encoder.finish()]);
        target.read_when_ready(&gpu)
    }
}

fn buffer(device: &wgpu::Device, bytes: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("mesh"),
        size: bytes.max(16),
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
