"""A third-party avatar driver for tests/test_rig.py: loaded as tests.avatar_driver_plugin:drive."""

import torch

from lenticalib.render.avatar.gaussians import Gaussians

control_dim_value = 4
not_callable = 3


def drive(controls, device):
    """Two Gaussians, the first moved along x by controls[0]."""
    means = torch.zeros(2, 3, device=device)
    means[0, 0] = controls[0]
    return Gaussians(means=means, quats=torch.tensor([[1.0, 0, 0, 0]] * 2, device=device),
                     scales=torch.full((2, 3), 0.01, device=device), opacities=torch.full((2,), 0.9, device=device),
                     sh=torch.zeros(2, 1, 3, device=device))


drive.control_dim = control_dim_value


def bad_return(controls, device):
    return {"means": controls}


class Namespace:
    @staticmethod
    def method(controls, device):
        return drive(controls, device)
