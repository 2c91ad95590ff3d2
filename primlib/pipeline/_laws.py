"""The fixed set of ILC laws the pipeline runs (kept import-free, so the CLI's options can
list them without loading the learners)."""

from __future__ import annotations

__all__ = ["LAWS", "ILC_LAWS", "MASTER_SLAVE_LAWS"]

# laws of primlib.ilc.learn (any number of axes)
ILC_LAWS = ("p", "pd", "pid", "norm-optimal")
# laws of the master-slave PDCCILC paper: two-axis machines, primlib.ilc.learn_master_slave
MASTER_SLAVE_LAWS = ("tdilc", "tdccilc", "pdilc", "pdccilc")
LAWS = ILC_LAWS + MASTER_SLAVE_LAWS
