"""Studies built on the learner: the validation selection (``select``), the latent-dimension sweep
(``sweep``), the paper's reproduction (``reproduce``), fine-tuning runs (``finetune``)."""

# What a local worker of the selection's grid imports once, in the pools' fork server
# (``symrom.execution.Backend.prestart``): named here, so that a command can start that server
# before it imports the selection itself
SELECT_WORKER_MODULES = ("symrom.experiments.select",)
