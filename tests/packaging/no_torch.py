"""Imported first, it makes `import torch` fail as on a machine without the `learn` extra."""

import sys


class NoTorch:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError("No module named 'torch'", name="torch")
        return None


sys.meta_path.insert(0, NoTorch())
