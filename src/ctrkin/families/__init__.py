"""The model families, one folder each, and their registry (docs/design.md: Model families).

    sequence/     the paper's LSTM-MLP, its Δα0 ablation and structures, the MLP, LSTM, CNN, TCN and
                  ResNet baselines (FK and IK)
    snap_aware/   the snap-aware FK (lstm_mlp_branch): a branch state set by a fold gate
    follow/       the follow IK (follow_mlp): joint changes from where the robot is
    refined/      an IK refined on a learned FK (assembled from two folders)
    registry.py   one line per family; what training and inference ask of them

A family imports no other family and not the registry; training and inference import families only
through the registry (tests/test_layering.py).

    from ctrkin.families.registry import MODELS, build_model
    from ctrkin.families.refined import assemble_refined
"""
