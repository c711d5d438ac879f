"""Fusion of several imaging channels weighted by detection probability (paper 004).

| module | role |
|--------|------|
| :mod:`.tracker` | the multi-channel fused angle tracker with weighted discriminators |
| :mod:`.variance` | accuracy of the fused system: relative posterior variance |
| :mod:`.detection_probability` | detection probability and detection parameter of a channel |
"""
