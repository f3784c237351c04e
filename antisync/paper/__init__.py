"""The paper: its printed numbers (``reference``) and every figure and table at reduced
realizations (``make``, behind ``antisync paper``).
"""
