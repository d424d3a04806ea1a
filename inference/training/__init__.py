"""Training and judging the encoder: the synthetic dataset (local or on a Ray cluster), the model and its
loss, training, ONNX export, evaluation on clean held-out swatches, and the model card.

Developer tools: they need the ``[train]`` extra (torch); the app's runtime path never imports them."""
