//! The shifted copies a k x k convolution reads (im2col), as one operation with its own
//! backward pass on the CPU backend.
//!
//! Training on flex computes a stride-1 k x k convolution as a matrix product over the k*k
//! shifted copies of its input (see `blocks::apply_conv`). Built from tensor operations
//! (pad, k*k narrows, cat) the copies cost twice the product itself, and their backward pass
//! more: every narrow's gradient is a zero tensor of the padded input's size with the slice
//! written into it, and the k*k of them are summed. Here the forward pass writes the copies
//! in one pass and the backward pass adds the k*k gradient planes back in one pass.

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{unary, Backward, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::tensor::FloatTensor;
use burn::backend::{backend_extension, Autodiff, Backend, Dispatch, Flex};
use burn::prelude::*;
use burn::tensor::{DType, Element, TensorData};
use rayon::prelude::*;

/// The extension: `shift_stack` on flex, with and without autodiff.
#[backend_extension(Flex, Autodiff)]
pub trait ShiftStackOps: Backend {
    /// [N, C, H, W] -> [N, k*k*C, H, W]: channel block s = dy * k + dx holds the input shifted
    /// so that pixel (i, j) reads input pixel (i + dy - k/2, j + dx - k/2), 0 outside.
    fn shift_stack(x: FloatTensor<Self>, kernel: usize) -> FloatTensor<Self>;
}

/// The shifted copies of `x` ([N, C, H, W]) for a k x k convolution with "same" padding,
/// [N, k*k*C, H, W], shift-major. Only on the CPU backend (flex), with or without autodiff.
pub fn shift_stack(x: Tensor<4>, kernel: usize) -> Tensor<4> {
    assert!(kernel % 2 == 1, "shift_stack takes odd kernels, got {kernel}");
    Tensor::from_dispatch(<Dispatch as ShiftStackOps>::shift_stack(x.into_dispatch(), kernel))
}

fn dims4(tensor: &FlexTensor) -> [usize; 4] {
    let shape = tensor.layout().shape();
    assert_eq!(shape.num_dims(), 4, "shift_stack takes [N, C, H, W] tensors");
    [shape[0], shape[1], shape[2], shape[3]]
}

/// The values the kernels take: f32, or f64 where a test asks for it.
trait Value: Element + bytemuck::Pod + Default + std::ops::AddAssign + Send + Sync {}
impl Value for f32 {}
impl Value for f64 {}

/// `out[j] = src[j + offset]`, 0 where `j + offset` is outside the row.
fn shifted_row<E: Value>(out: &mut [E], src: &[E], offset: isize) {
    let w = out.len() as isize;
    let (lo, hi) = ((-offset).clamp(0, w) as usize, (w - offset).clamp(0, w) as usize);
    if lo >= hi {
        out.fill(E::default());
        return;
    }
    out[..lo].fill(E::default());
    out[hi..].fill(E::default());
    out[lo..hi].copy_from_slice(&src[(lo as isize + offset) as usize..(hi as isize + offset) as usize]);
}

/// `row[x] += src[x - offset]` wherever `x - offset` is inside the row.
fn add_shifted_row<E: Value>(row: &mut [E], src: &[E], offset: isize) {
    let w = row.len() as isize;
    let (lo, hi) = (offset.clamp(0, w) as usize, (w + offset).clamp(0, w) as usize);
    if lo >= hi {
        return;
    }
    let src = &src[(lo as isize - offset) as usize..(hi as isize - offset) as usize];
    for (value, g) in row[lo..hi].iter_mut().zip(src) {
        *value += *g;
    }
}

impl ShiftStackOps for Flex {
    fn shift_stack(x: FlexTensor, kernel: usize) -> FlexTensor {
        let dims = dims4(&x);
        let x = x.to_contiguous();
        match x.dtype() {
            DType::F32 => stack::<f32>(x.as_slice().expect("contiguous"), kernel, dims),
            DType::F64 => stack::<f64>(x.as_slice().expect("contiguous"), kernel, dims),
            other => panic!("shift_stack takes f32 or f64 tensors, got {other:?}"),
        }
    }
}

fn stack<E: Value>(input: &[E], kernel: usize, [n, c, h, w]: [usize; 4]) -> FlexTensor {
    let (k, p) = (kernel, kernel / 2);
    let mut out = vec![E::default(); n * k * k * c * h * w];
    // One task per (image, shift): a block of C planes.
    out.par_chunks_mut(c * h * w).enumerate().for_each(|(task, block)| {
        let (b, s) = (task / (k * k), task % (k * k));
        let (dy, dx) = ((s / k) as isize - p as isize, (s % k) as isize - p as isize);
        for (ch, plane) in block.chunks_mut(h * w).enumerate() {
            let src = &input[(b * c + ch) * h * w..][..h * w];
            for (i, row) in plane.chunks_mut(w).enumerate() {
                let y = i as isize + dy;
                if y < 0 || y >= h as isize {
                    row.fill(E::default());
                } else {
                    shifted_row(row, &src[y as usize * w..][..w], dx);
                }
            }
        }
    });
    FlexTensor::from_data(TensorData::new(out, [n, k * k * c, h, w]))
}

/// The backward pass: the gradient of the input ([N, C, H, W]) from the copies' ([N, k*k*C,
/// H, W]): every input pixel collects the gradient of each copy at the pixel that read it.
fn shift_stack_backward(grad: FlexTensor, kernel: usize, dims: [usize; 4]) -> FlexTensor {
    let grad = grad.to_contiguous();
    match grad.dtype() {
        DType::F32 => unstack::<f32>(grad.as_slice().expect("contiguous"), kernel, dims),
        DType::F64 => unstack::<f64>(grad.as_slice().expect("contiguous"), kernel, dims),
        other => panic!("shift_stack takes f32 or f64 tensors, got {other:?}"),
    }
}

fn unstack<E: Value>(grad: &[E], kernel: usize, [n, c, h, w]: [usize; 4]) -> FlexTensor {
    let (k, p) = (kernel, kernel / 2);
    let mut out = vec![E::default(); n * c * h * w];
    out.par_chunks_mut(h * w).enumerate().for_each(|(plane_index, plane)| {
        let (b, ch) = (plane_index / c, plane_index % c);
        for s in 0..k * k {
            let (dy, dx) = ((s / k) as isize - p as isize, (s % k) as isize - p as isize);
            let src = &grad[((b * k * k + s) * c + ch) * h * w..][..h * w];
            // Copy pixel (i, j) read input (i + dy, j + dx): input row y gets copy row y - dy.
            for y in 0..h as isize {
                let i = y - dy;
                if i < 0 || i >= h as isize {
                    continue;
                }
                add_shifted_row(&mut plane[y as usize * w..][..w], &src[i as usize * w..][..w], dx);
            }
        }
    });
    FlexTensor::from_data(TensorData::new(out, [n, c, h, w]))
}

impl<C: CheckpointStrategy> ShiftStackOps for Autodiff<Flex, C> {
    fn shift_stack(x: FloatTensor<Self>, kernel: usize) -> FloatTensor<Self> {
        #[derive(Debug)]
        struct ShiftStackBackward;

        impl Backward<Flex, 1> for ShiftStackBackward {
            type State = (usize, [usize; 4]);

            fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _checkpointer: &mut Checkpointer) {
                let (kernel, dims) = ops.state;
                unary::<Flex, _>(ops.parents, ops.node, grads, |grad| shift_stack_backward(grad, kernel, dims));
            }
        }

        let dims = dims4(x.primitive());
        match ShiftStackBackward.prepare::<C>([x.node()]).compute_bound().stateful() {
            OpsKind::Tracked(prep) => prep.finish((kernel, dims), Flex::shift_stack(x.into_primitive(), kernel)),
            OpsKind::UnTracked(prep) => prep.finish(Flex::shift_stack(x.into_primitive(), kernel)),
        }
    }
}
