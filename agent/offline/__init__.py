"""The offline family (nb, bt, opt): a plan from the a-priori map, walked and taken over."""
