"""Learning laws: the protocol and memory format (:mod:`.base`), the learning filters
(:mod:`.filters`) and one module per law (``rptc``: repetitive PTC, paper 000)."""
