"""Learned reconstruction: SJDD-Net and torch models as methods (a face; no logic here).

Public names::

    from spikejdd.models import SJDDNet, SJDDConfig, DEFAULT, LITE, PUBLISHED, load_pretrained
    model = SJDDNet(LITE)                         # or SJDDNet() = published widths
    rgb, noise_map = model(spikes, mask)          # (N, 39, H, W), (N, 4, H, W)
    model = load_pretrained("sjdd-lite")          # a shipped checkpoint (spikejdd/weights)
    TorchMethod(module, window=39)                # any nn.Module as a reconstruction method
    run_ensemble(module, x, "RGGB", 2)            # mean over geometric views (``ensemble``)
    sj.reconstruct(spikes, cfa="RGGB", method="sjdd", center=19)

Modules: :mod:`~spikejdd.models.sjdd` (architecture), :mod:`~.deform`
(deformable convolution), :mod:`~.checkpoints` (format, published
conversion), :mod:`~.pretrained` (shipped weights, reference outputs, model
cache), :mod:`~.adapter` (the method protocol for torch modules; ``sjdd``).
The registry (:mod:`spikejdd.registry`) names ``"sjdd"`` lazily; this package
does not import it.
"""

from __future__ import annotations

from spikejdd.models.adapter import ENSEMBLES, TorchMethod, model_inputs, run_ensemble, sjdd_method
from spikejdd.models.checkpoints import (
    CheckpointError,
    check_state_dict,
    convert_published_state_dict,
    load_checkpoint,
    load_model,
    save_checkpoint,
    to_published_state_dict,
)
from spikejdd.models.deform import DeformConv2d, deform_conv2d, torchvision_available
from spikejdd.models.pretrained import (
    DEFAULT_WEIGHTS,
    WEIGHTS_DIR,
    cached_model,
    list_pretrained,
    load_pretrained,
    pretrained_path,
    reference_check,
    reference_input,
    resolve_weights,
    write_reference,
)
from spikejdd.models.sjdd import (
    DEFAULT,
    LITE,
    PUBLISHED,
    PUBLISHED_PARAMETERS,
    SJDDConfig,
    SJDDNet,
    count_parameters,
)

__all__ = ["SJDDNet", "SJDDConfig", "DEFAULT", "LITE", "PUBLISHED", "PUBLISHED_PARAMETERS",
           "load_pretrained", "list_pretrained", "pretrained_path", "resolve_weights",
           "cached_model", "DEFAULT_WEIGHTS", "WEIGHTS_DIR", "sjdd_method", "TorchMethod",
           "run_ensemble", "ENSEMBLES",
           "model_inputs", "save_checkpoint", "load_checkpoint", "load_model",
           "convert_published_state_dict", "to_published_state_dict", "check_state_dict",
           "CheckpointError", "DeformConv2d", "deform_conv2d", "torchvision_available",
           "count_parameters", "reference_input", "reference_check", "write_reference"]
