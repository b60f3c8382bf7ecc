#!/usr/bin/env python3
"""Writes tiny ONNX detection models with known outputs for the detect tests (issue #7 item 3).

No trained weights can be downloaded here, so the ONNX backend's loading, decoding and NMS are tested
on models built from a few operators that OpenCV 4.6's ONNX importer reads:

    images [1, 3, S, S] -> GlobalAveragePool -> 1x1 Conv (bias = the known output) -> Reshape -> output

The Conv's weights are zero except one: the score of the first box is bias + GAIN * mean(channel 0),
so a test that knows its image can check that the preprocessing ran (BGR -> RGB, / 255, the
letterbox and its pad value 114). Every other number is the bias, i.e. fixed.

Models (S = 64, classes fillet = 0, butt = 1; box coordinates in model input pixels):
  tiny_yolo_e2e.onnx          YOLOv10 NMS-free head [1, 300, 6]: x1 y1 x2 y2 score class
  tiny_yolo_raw.onnx          YOLOv8-style head [1, 4 + 2, 8]: cx cy w h, then a score per class
  tiny_yolo_bad_output.onnx   output [1, 7, 5]: no head layout (incompatible)
  tiny_yolo_input16.onnx      made for a 16 x 16 input (Flatten -> Gemm): a forward pass on a 64 x 64
                              blob fails (incompatible input)

The boxes below are repeated in tests/detect/test_onnx_detector.cpp; change both together.
Usage: make_tiny_yolo.py OUTPUT_DIR
"""

import os
import sys

try:
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper
except ImportError as e:  # the build calls this script; say what to install
    sys.exit(f"make_tiny_yolo.py: python3 module missing ({e}): run toolchain/install-deps.sh "
             "(Debian python3-onnx, python3-numpy)")

SIZE = 64
GAIN = 0.3  # score of the first box = bias + GAIN * mean of the blob's channel 0 (R after the swap)

# End-to-end rows: x1 y1 x2 y2 score class. Row 0's score is 0.55 + GAIN * mean(R).
E2E_ROWS = [
    [20.0, 20.0, 40.0, 36.0, 0.55, 0.0],  # a fillet in the middle of the letterboxed image
    [4.0, 12.0, 14.0, 22.0, 0.9, 1.0],    # a butt on the left
    [44.0, 30.0, 60.0, 50.0, 0.1, 0.0],  # below the score threshold (0.25)
    [30.0, 58.0, 40.0, 63.0, 0.8, 0.0],  # within the letterbox's grey band (rows 56-63 for 4:3): outside
]
E2E_ANCHORS = 300

# Raw head anchors: cx cy w h, score fillet, score butt. Anchor 0's fillet score is 0.55 + GAIN * mean(R)
# (> 0.55: above anchor 1's whatever the image).
RAW_ANCHORS = [
    [30.0, 28.0, 20.0, 16.0, 0.55, 0.05],  # a fillet in the middle: (20, 20) - (40, 36)
    [31.0, 28.0, 20.0, 16.0, 0.5, 0.02],   # overlaps anchor 0 (IoU 0.90), same class, less confident: suppressed
    [31.0, 29.0, 20.0, 16.0, 0.01, 0.7],   # overlaps anchor 0, other class: kept
    [9.0, 17.0, 10.0, 10.0, 0.1, 0.8],     # a butt on the left: (4, 12) - (14, 22)
    [50.0, 40.0, 12.0, 12.0, 0.1, 0.2],    # below the score threshold
]
RAW_ANCHOR_COUNT = 8
NUM_CLASSES = 2


def conv_model(name, bias, out_shape, gain_index=None):
    """images -> GlobalAveragePool -> 1x1 Conv (len(bias) channels) -> Reshape(out_shape) -> output."""
    channels = len(bias)
    weight = np.zeros((channels, 3, 1, 1), dtype=np.float32)
    if gain_index is not None:
        weight[gain_index, 0, 0, 0] = GAIN
    nodes = [
        helper.make_node("GlobalAveragePool", ["images"], ["pooled"]),
        helper.make_node("Conv", ["pooled", "conv_w", "conv_b"], ["conv"], kernel_shape=[1, 1]),
        helper.make_node("Reshape", ["conv", "out_shape"], ["output"]),
    ]
    inits = [
        numpy_helper.from_array(weight, "conv_w"),
        numpy_helper.from_array(np.asarray(bias, dtype=np.float32), "conv_b"),
        numpy_helper.from_array(np.asarray(out_shape, dtype=np.int64), "out_shape"),
    ]
    graph = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, SIZE, SIZE])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, list(out_shape))],
        inits)
    model = helper.make_model(graph, producer_name="hwr make_tiny_yolo.py",
                              opset_imports=[helper.make_opsetid("", 11)])
    model.ir_version = 7  # what OpenCV 4.6's bundled ONNX reader knows
    onnx.checker.check_model(model)
    return model


def fixed_input_model(name, size=16, rows=10):
    """images [1, 3, size, size] -> Flatten -> Gemm -> Reshape [1, rows, 6]: the Gemm's weights fix the
    input size, as a real network's do (a 1x1 Conv after a global pool would take any size)."""
    inputs = 3 * size * size
    nodes = [
        helper.make_node("Flatten", ["images"], ["flat"], axis=1),
        helper.make_node("Gemm", ["flat", "gemm_w", "gemm_b"], ["gemm"], transB=1),
        helper.make_node("Reshape", ["gemm", "out_shape"], ["output"]),
    ]
    inits = [
        numpy_helper.from_array(np.zeros((rows * 6, inputs), dtype=np.float32), "gemm_w"),
        numpy_helper.from_array(np.zeros(rows * 6, dtype=np.float32), "gemm_b"),
        numpy_helper.from_array(np.asarray([1, rows, 6], dtype=np.int64), "out_shape"),
    ]
    graph = helper.make_graph(
        nodes, name, [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, size, size])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, rows, 6])], inits)
    model = helper.make_model(graph, producer_name="hwr make_tiny_yolo.py",
                              opset_imports=[helper.make_opsetid("", 11)])
    model.ir_version = 7
    onnx.checker.check_model(model)
    return model


def e2e_bias():
    out = np.zeros((E2E_ANCHORS, 6), dtype=np.float32)
    out[:len(E2E_ROWS)] = np.asarray(E2E_ROWS, dtype=np.float32)
    return out.reshape(-1), 0 * 6 + 4  # row 0's score


def raw_bias():
    out = np.zeros((4 + NUM_CLASSES, RAW_ANCHOR_COUNT), dtype=np.float32)  # [1, 4 + C, N]: row-major
    out[:, :len(RAW_ANCHORS)] = np.asarray(RAW_ANCHORS, dtype=np.float32).T
    return out.reshape(-1), 4 * RAW_ANCHOR_COUNT + 0  # anchor 0's fillet score


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make_tiny_yolo.py OUTPUT_DIR")
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    bias, gain_index = e2e_bias()
    models = {
        "tiny_yolo_e2e.onnx": conv_model("tiny_yolo_e2e", bias, [1, E2E_ANCHORS, 6], gain_index=gain_index),
        "tiny_yolo_input16.onnx": fixed_input_model("tiny_yolo_input16"),
        "tiny_yolo_bad_output.onnx": conv_model("tiny_yolo_bad_output", np.zeros(35), [1, 7, 5]),
    }
    bias, gain_index = raw_bias()
    models["tiny_yolo_raw.onnx"] = conv_model("tiny_yolo_raw", bias, [1, 4 + NUM_CLASSES, RAW_ANCHOR_COUNT],
                                              gain_index=gain_index)
    for file_name, model in models.items():
        # Write then rename, so that an interrupted build never leaves a half-written model behind.
        path = os.path.join(out_dir, file_name)
        onnx.save(model, path + ".tmp")
        os.replace(path + ".tmp", path)


if __name__ == "__main__":
    main()
