"""The checks of data and answers: input validation helpers (`validation`), the self-check run
on every answer (`self_check`) and the plausibility of a cell's files (`plausibility`).
"""
