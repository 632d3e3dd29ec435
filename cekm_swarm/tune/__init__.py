"""Field parameters learned, not hand-tuned (the paper's future work, end of section 4.2;
docs/fields.md): the features a robot's fields see (:mod:`.features`), a small policy that
sets the field widths from them (:mod:`.policy`), the motor node that applies it
(:mod:`.motor`), a Gymnasium environment over the in-process runner (:mod:`.env`), the
generated training scenarios (:mod:`.scenarios`) and the evolution strategy that trains
the policy (:mod:`.train`, ``cekm tune fields``)."""
