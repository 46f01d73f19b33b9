"""The multi-agent policies on BenchMARL and TorchRL (extras ``[benchmarl]``, ``[torchrl]``): the
tasks, the batched TorchRL env, training (``python -m baselines.marl.benchmarl_train``) and the
``mappo`` / ``ippo`` controllers, which play an export with numpy alone."""
