"""The ``silpose`` subcommands of silpose-app (entry points in the group ``silpose.commands``):
``train`` (:mod:`.train`) and ``infer`` (:mod:`.infer`)."""
