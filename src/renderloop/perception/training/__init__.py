"""Training the pepper detector (needs the `train` extra: torch, torchvision, onnx; pycocotools is a base dependency)."""
