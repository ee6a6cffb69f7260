//! Operations the CPU backend (flex) runs as one pass each, forward and backward, where
//! burn composes them from several tensor operations: the shifted copies a k x k convolution
//! reads (im2col) and the leaky ReLU.
//!
//! Training on flex computes a stride-1 k x k convolution as a matrix product over the k*k
//! shifted copies of its input (see `convolution`). Built from tensor operations
//! (pad, k*k narrows, cat) the copies cost twice the product itself, and their backward pass
//! more: every narrow's gradient is a zero tensor of the padded input's size with the slice
//! written into it, and the k*k of them are summed. Here the forward pass writes the copies
//! in one pass and the backward pass adds the k*k gradient planes back in one pass.
//!
//! burn's leaky ReLU is a comparison, a scaled copy and a masked select, and its backward pass
//! two more masked selects: a tenth of a GlassNet training step. Here, when training, it is one
//! pass each way.

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

/// The extension: the operations on flex, with and without autodiff.
#[backend_extension(Flex, Autodiff)]
pub trait FlexOps: Backend {
    /// [N, C, H, W] -> [N, k*k*C, H, W]: channel block s = dy * k + dx holds the input shifted
    /// so that pixel (i, j) reads input pixel (i + dy - k/2, j + dx - k/2), 0 outside.
    fn shift_stack(x: FloatTensor<Self>, kernel: usize) -> FloatTensor<Self>;
    /// x where x >= 0, slope * x elsewhere.
    fn leaky_relu(x: FloatTensor<Self>, slope: f64) -> FloatTensor<Self>;
}

/// The shifted copies of `x` ([N, C, H, W]) for a k x k convolution with "same" padding,
/// [N, k*k*C, H, W], shift-major. Only on the CPU backend (flex), with or without autodiff.
pub fn shift_stack(x: Tensor<4>, kernel: usize) -> Tensor<4> {
    assert!(kernel % 2 == 1, "shift_stack takes odd kernels, got {kernel}");
    Tensor::from_dispatch(<Dispatch as FlexOps>::shift_stack(x.into_dispatch(), kernel))
}

/// The leaky ReLU of `x`: x where x >= 0, `slope` x elsewhere. One pass each way when training
/// on flex (f32 or f64); burn's own otherwise, which without gradients is faster on flex (it
/// masks in place: 15-17 vs 19-21 ms for the quick GlassNet's forward pass, `cargo run
/// --release -p glassbake-bake --example train_step`).
pub fn leaky_relu(x: Tensor<4>, slope: f64) -> Tensor<4> {
    let device = x.device();
    let training_on_flex = device.is_autodiff() && crate::device::is_cpu(device);
    if training_on_flex && matches!(x.dtype(), DType::F32 | DType::F64) {
        Tensor::from_dispatch(<Dispatch as FlexOps>::leaky_relu(x.into_dispatch(), slope))
    } else {
        burn::tensor::activation::leaky_relu(x, slope)
    }
}

fn dims4(tensor: &FlexTensor) -> [usize; 4] {
    let shape = tensor.layout().shape();
    assert_eq!(shape.num_dims(), 4, "shift_stack takes [N, C, H, W] tensors");
    [shape[0], shape[1], shape[2], shape[3]]
}

/// The values the kernels take: f32, or f64 where a test asks for it.
trait Value: Element + bytemuck::Pod + Default + PartialOrd + std::ops::AddAssign + std::ops::Mul<Output = Self> + Send + Sync {}
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

impl FlexOps for Flex {
    fn shift_stack(x: FlexTensor, kernel: usize) -> FlexTensor {
        let dims = dims4(&x);
        let x = x.to_contiguous();
        match x.dtype() {
            DType::F32 => stack::<f32>(x.as_slice().expect("contiguous"), kernel, dims),
            DType::F64 => stack::<f64>(x.as_slice().expect("contiguous"), kernel, dims),
            other => panic!("shift_stack takes f32 or f64 tensors, got {other:?}"),
        }
    }

    fn leaky_relu(x: FlexTensor, slope: f64) -> FlexTensor {
        fn apply<E: Value>(x: FlexTensor, slope: E) -> FlexTensor {
            let shape = x.layout().shape().clone();
            let mut values = x.to_contiguous().as_slice::<E>().expect("contiguous").to_vec();
            values.par_chunks_mut(PARALLEL_CHUNK).for_each(|chunk| {
                for v in chunk {
                    if *v < E::default() {
                        *v = *v * slope;
                    }
                }
            });
            FlexTensor::from_data(TensorData::new(values, shape))
        }
        match x.dtype() {
            DType::F32 => apply::<f32>(x, slope as f32),
            DType::F64 => apply::<f64>(x, slope),
            other => panic!("leaky_relu takes f32 or f64 tensors, got {other:?}"),
        }
    }
}

/// Elements per task when an element-wise pass is split over the thread pool.
const PARALLEL_CHUNK: usize = 1 << 14;

/// The leaky ReLU's backward pass from its output `y` (negative exactly where its input was).
fn leaky_relu_backward(grad: FlexTensor, y: &FlexTensor, slope: f64) -> FlexTensor {
    let (grad, y) = (grad.to_contiguous(), y.to_contiguous());
    let shape = grad.layout().shape().clone();
    fn zip<E: Value>(grad: &[E], y: &[E], shape: Shape, slope: E) -> FlexTensor {
        assert_eq!(grad.len(), y.len(), "a gradient of the output's size");
        let mut out = vec![E::default(); grad.len()];
        out.par_chunks_mut(PARALLEL_CHUNK).zip(grad.par_chunks(PARALLEL_CHUNK).zip(y.par_chunks(PARALLEL_CHUNK))).for_each(|(out, (grad, y))| {
            for ((o, &g), &y) in out.iter_mut().zip(grad).zip(y) {
                *o = if y < E::default() { g * slope } else { g };
            }
        });
        FlexTensor::from_data(TensorData::new(out, shape))
    }
    match grad.dtype() {
        DType::F32 => zip::<f32>(grad.as_slice().expect("contiguous"), y.as_slice().expect("contiguous"), shape, slope as f32),
        DType::F64 => zip::<f64>(grad.as_slice().expect("contiguous"), y.as_slice().expect("contiguous"), shape, slope),
        other => panic!("leaky_relu takes f32 or f64 tensors, got {other:?}"),
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

impl<C: CheckpointStrategy> FlexOps for Autodiff<Flex, C> {
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

    fn leaky_relu(x: FloatTensor<Self>, slope: f64) -> FloatTensor<Self> {
        #[derive(Debug)]
        struct LeakyReluBackward;

        impl Backward<Flex, 1> for LeakyReluBackward {
            // The output, which the next layer keeps for its own backward pass anyway.
            type State = (FlexTensor, f64);

            fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _checkpointer: &mut Checkpointer) {
                let (y, slope) = ops.state;
                unary::<Flex, _>(ops.parents, ops.node, grads, |grad| leaky_relu_backward(grad, &y, slope));
            }
        }

        match LeakyReluBackward.prepare::<C>([x.node()]).compute_bound().stateful() {
            OpsKind::Tracked(prep) => {
                let y = Flex::leaky_relu(x.into_primitive(), slope);
                prep.finish((y.clone(), slope), y)
            }
            OpsKind::UnTracked(prep) => prep.finish(Flex::leaky_relu(x.into_primitive(), slope)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    /// One pass each way against burn's composed leaky ReLU when training: the same values and
    /// the same input gradient, zeros included (slope 1 there, as burn's), on an input and on
    /// a computed one.
    #[test]
    fn leaky_relu_matches_burns() {
        let device = Device::flex().autodiff();
        device.seed(3);
        let mut x = values(Tensor::<4>::random([2, 3, 5, 7], Distribution::Uniform(-1.0, 1.0), &device));
        x[..10].fill(0.0);
        let x = Tensor::<4>::from_data(TensorData::new(x, [2, 3, 5, 7]), &device).require_grad();
        let r = Tensor::<4>::random([2, 3, 5, 7], Distribution::Uniform(-1.0, 1.0), &device);
        let fresh = |x: &Tensor<4>| x.clone().mul_scalar(2.0);
        for (what, ours, theirs) in [
            ("held input", leaky_relu(x.clone(), 0.1), burn::tensor::activation::leaky_relu(x.clone(), 0.1)),
            ("fresh input", leaky_relu(fresh(&x), 0.1), burn::tensor::activation::leaky_relu(fresh(&x), 0.1)),
        ] {
            assert_eq!(values(ours.clone()), values(theirs.clone()), "{what}");
            let (g_ours, g_theirs) = ((ours * r.clone()).sum().backward(), (theirs * r.clone()).sum().backward());
            let grad = |g| x.grad(g).unwrap().into_data().try_to_vec::<f32>().unwrap();
            assert_eq!(grad(&g_ours), grad(&g_theirs), "{what}");
        }
    }
}
