"""The thesis's behaviour (Appendix A): search, touch, claim, field, transport."""
